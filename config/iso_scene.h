/* config/iso_scene.h -- scene files: one YAML file that says what to run.
 *
 * A scene names the mesh, its fixed and handle regions, what drives each
 * handle (a device through a mapping, or a scripted path), the solver and
 * integrator settings, the tick rate, the devices, the sinks (display, PLY
 * frames, actuators over the firmware bridge) and the recording. The schema
 * is documented in config/SCENES.md.
 *
 * iso_scene_load() reads the file with libfyaml into a plain struct and
 * validates all of it: every error is one sentence that starts with
 * "FILE:LINE:COL: KEY: " and says what was expected. Unknown keys are errors
 * with the nearest known key suggested. Files named in a scene are relative
 * to the scene file's folder. The mesh is loaded and the regions built, so a
 * selection that selects nothing or a vertex both fixed and on a handle is
 * caught here; building the solver (ill-posed constraints) is the caller's
 * step (isoshape check does it).
 *
 * Codes: ISO_EPARSE for YAML syntax, unknown keys, wrong types and missing
 * keys; ISO_EINVAL for values out of range; ISO_EIO for a named file that
 * does not exist or cannot be read; ISO_ECONSTRAINT for regions that do not
 * make sense (empty selection, overlap); the mesh loader's own codes for a
 * bad mesh. The scene struct is heap-owned: iso_scene_destroy() frees it. */
#ifndef ISO_SCENE_H
#define ISO_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "iso_actuators.h" /* the sink a scene's actuators become */
#include "iso_dev_map.h"
#include "iso_dev_source.h"
#include "iso_err.h"
#include "iso_integrate.h"
#include "iso_mesh.h"
#include "iso_motion.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "iso_solver.h"

#define ISO_SCENE_PATH_MAX 4096
#define ISO_SCENE_NAME_MAX 64
#define ISO_SCENE_MAX_HANDLES ((int)ISO_DEV_MAX_HANDLES)
#define ISO_SCENE_MAX_DEVICES ((int)ISO_DEV_MAX_SOURCES)
#define ISO_SCENE_MAX_SELECT 16 /* selection items per region */
#define ISO_SCENE_MAX_KEYFRAMES 64
#define ISO_SCENE_MAX_CHANNELS 32
#define ISO_SCENE_MAX_SNAPSHOTS 32

/* ---- mesh ---------------------------------------------------------------- */
typedef enum iso_scene_mesh_kind {
    ISO_SCENE_MESH_FILE = 1,     /* mesh: FILE */
    ISO_SCENE_MESH_SHAPE = 2,    /* mesh: {shape: NAME, resolution: N} */
    ISO_SCENE_MESH_BENCHMARK = 3 /* mesh: {benchmark: NAME, fallback_shape: NAME} */
} iso_scene_mesh_kind;

typedef struct iso_scene_mesh_src {
    int kind;                                /* iso_scene_mesh_kind as written */
    char path[ISO_SCENE_PATH_MAX];           /* FILE, resolved against the scene's folder */
    char shape[ISO_SHAPE_NAME_MAX];          /* SHAPE */
    int resolution;                          /* SHAPE or fallback: 0 = default */
    char benchmark[ISO_SCENE_NAME_MAX];      /* BENCHMARK */
    char fallback_shape[ISO_SHAPE_NAME_MAX]; /* "" = none: a missing benchmark is an error */
    int line, col;                           /* where `mesh:` was written */
    /* After loading: what was used. */
    int used;                           /* FILE, SHAPE (also a fallback) or BENCHMARK */
    char sel[ISO_SCENE_PATH_MAX];       /* the benchmark's .sel ("" otherwise) */
    char def[ISO_SCENE_PATH_MAX];       /* the benchmark's .def ("" otherwise) */
    char note[ISO_SCENE_PATH_MAX + 64]; /* why the fallback stood in, "" if it did not */
} iso_scene_mesh_src;

/* ---- selections ------------------------------------------------------------ */
typedef enum iso_scene_sel_kind {
    ISO_SCENE_SEL_VERTICES = 1, /* {vertices: [i, ...]} */
    ISO_SCENE_SEL_BOX = 2,      /* {box: {min: [x,y,z], max: [x,y,z]}} */
    ISO_SCENE_SEL_SPHERE = 3,   /* {sphere: {center: [x,y,z], radius: r}} */
    ISO_SCENE_SEL_PLANE = 4     /* {beyond: {point: [x,y,z], normal: [x,y,z]}} */
} iso_scene_sel_kind;

typedef struct iso_scene_sel {
    int kind;
    int line, col; /* where it was written, for messages */
    int *vertices; /* VERTICES: owned */
    int n_vertices;
    double a[3], b[3]; /* BOX min/max; SPHERE centre; PLANE point/normal */
    double radius;     /* SPHERE */
} iso_scene_sel;

typedef struct iso_scene_region {
    iso_scene_sel sel[ISO_SCENE_MAX_SELECT]; /* union of these */
    int n_sel;
    int count; /* after loading: vertices selected */
} iso_scene_region;

/* ---- handle drivers ------------------------------------------------------------ */
typedef enum iso_scene_driver_kind {
    ISO_SCENE_DRIVE_NONE = 0,   /* held still */
    ISO_SCENE_DRIVE_DEVICE = 1, /* a device through a mapping */
    ISO_SCENE_DRIVE_SCREW = 2,  /* a .def screw motion over a duration */
    ISO_SCENE_DRIVE_KEYFRAMES = 3
} iso_scene_driver_kind;

typedef struct iso_scene_keyframe {
    double t;            /* seconds from the start, strictly increasing */
    double translate[3]; /* scene units */
    double rotate[3];    /* rotation vector, degrees (axis times angle) */
} iso_scene_keyframe;

typedef struct iso_scene_driver {
    int kind;
    int device;                   /* DEVICE: index in scene->devices */
    iso_dev_map_opts map;         /* DEVICE: the mapping (devices layer defaults + scene) */
    char def[ISO_SCENE_PATH_MAX]; /* SCREW: the .def file, "" = the mesh source's own */
    double M[16];                 /* SCREW: the final transform (row-major) */
    iso_twist twist;              /* SCREW: its twist (iso_twist_from_matrix) */
    double duration;              /* SCREW: seconds, > 0 */
    iso_scene_keyframe keys[ISO_SCENE_MAX_KEYFRAMES];
    int n_keys;
} iso_scene_driver;

typedef struct iso_scene_handle {
    char name[ISO_SCENE_NAME_MAX];
    int from_sel; /* 1: no select: the base regions' handle of this index */
    iso_scene_region region;
    iso_scene_driver driver;
} iso_scene_handle;

/* ---- devices ----------------------------------------------------------------- */
typedef enum iso_scene_dev_backend {
    ISO_SCENE_DEV_HIDAPI = 1, /* path ("" = first 3D mouse), vid, pid */
    ISO_SCENE_DEV_SPNAV,      /* spacenavd */
    ISO_SCENE_DEV_TTY,        /* path, baud */
    ISO_SCENE_DEV_TCP,        /* address "host:port" */
    ISO_SCENE_DEV_SERIALPORT, /* path (port name), baud */
    ISO_SCENE_DEV_GPIOD,      /* chip, clutch/estop/pulse lines, active_low, debounce */
    ISO_SCENE_DEV_REPLAY,     /* path: a recording (.isorec) */
    ISO_SCENE_DEV_VIEW        /* the live view's page (at most one; needs sinks.display) */
} iso_scene_dev_backend;

typedef struct iso_scene_device {
    char name[ISO_SCENE_NAME_MAX];
    int backend;                          /* iso_scene_dev_backend */
    char path[ISO_SCENE_PATH_MAX];        /* device node, port, recording (resolved) */
    char address[ISO_SCENE_NAME_MAX * 2]; /* TCP host:port */
    uint32_t baud;
    uint16_t vid, pid;
    iso_dev_gpio_opts gpio; /* GPIOD; gpio.chip points at `chip` */
    char chip[ISO_SCENE_NAME_MAX];
    /* TTY, TCP, SERIALPORT, REPLAY, VIEW: a twist or target stream's stale
     * time in ms (key `stale_ms`): this long without a sample and it stops
     * moving its handle (iso_dev_map_set_stale). Other kinds hold the
     * default, unused. */
    int stale_ms; /* 0: not given; each source's kind's default then */
} iso_scene_device;
#define ISO_SCENE_STALE_MS_DEFAULT 100 /* = ISO_DEV_STALE_DEFAULT_NS */
/* A view's default: a page in control sends its target every 25 ms, but a
 * browser on a busy machine delivers 12-30 a second, and a foreground tab's
 * timers slip by tens of ms more; at 100 ms a drag stuttered with pairs of
 * stale and resume notices. 250 ms is three periods at 12 a second. */
#define ISO_SCENE_STALE_MS_VIEW_DEFAULT 250
#define ISO_SCENE_STALE_MS_MIN 1     /* = ISO_DEV_STALE_MIN_NS */
#define ISO_SCENE_STALE_MS_MAX 10000 /* = ISO_DEV_STALE_MAX_NS */
_Static_assert(ISO_SCENE_STALE_MS_DEFAULT * 1000000LL == ISO_DEV_STALE_DEFAULT_NS &&
                   ISO_SCENE_STALE_MS_MIN * 1000000LL == ISO_DEV_STALE_MIN_NS &&
                   ISO_SCENE_STALE_MS_MAX * 1000000LL == ISO_DEV_STALE_MAX_NS,
               "the scene's stale_ms range is the devices layer's");

/* ---- sinks ----------------------------------------------------------------- */
typedef struct iso_scene_display {
    int enabled;
    char host[ISO_SCENE_NAME_MAX]; /* default 127.0.0.1 */
    int port;                      /* default 8080 */
    int allow_remote;              /* 1: a host beyond loopback may be bound (with a warning) */
    long snapshot_ticks[ISO_SCENE_MAX_SNAPSHOTS]; /* PNG snapshots at these ticks */
    int n_snapshots;
    char snapshot_dir[ISO_SCENE_PATH_MAX];
} iso_scene_display;

typedef struct iso_scene_ply {
    int enabled;
    char dir[ISO_SCENE_PATH_MAX]; /* resolved against the scene's folder */
    int every;                    /* one frame per `every` ticks, >= 1 */
} iso_scene_ply;

typedef enum iso_scene_link_kind {
    ISO_SCENE_LINK_TTY = 1,    /* path, baud */
    ISO_SCENE_LINK_TCP = 2,    /* host, port */
    ISO_SCENE_LINK_SERIAL = 3, /* path (libserialport name), baud */
    ISO_SCENE_LINK_EMULATED =
        4, /* emulation: firmware in QEMU or in-process (actuators/iso_actuators.h) */
    ISO_SCENE_LINK_USB = 5 /* vid, pid: a bridge on USB bulk endpoints (libusb) */
} iso_scene_link_kind;

/* Which emulated MCU; the values are actuators/iso_actuators.h's ISO_ACT_EMU_*. */
typedef enum iso_scene_emu_mode {
    ISO_SCENE_EMU_AUTO = 0,  /* QEMU when it and the firmware ELF are there, else native */
    ISO_SCENE_EMU_QEMU = 1,  /* QEMU or an error */
    ISO_SCENE_EMU_NATIVE = 2 /* the MCU logic in a thread behind a pty */
} iso_scene_emu_mode;

typedef struct iso_scene_channel {
    int channel;     /* actuator channel, 0..ISO_ACT_MAX_CHANNELS-1 (a SETPOINTS frame's
                        index), each once */
    int vertex;      /* a vertex, or -1 */
    int region;      /* or a region's centroid (see below) */
    int axis;        /* 0 x, 1 y, 2 z */
    double min, max; /* limits, min < max (scene units) */
    double scale;    /* scene units to actuator counts, default 1 */
    int line, col;   /* where it was written, for messages */
} iso_scene_channel;
/* region: ISO_SCENE_REGION_FIXED, or a handle index >= 0; ISO_SCENE_REGION_NONE
 * when the channel follows a vertex. */
#define ISO_SCENE_REGION_NONE (-2)
#define ISO_SCENE_REGION_FIXED (-1)

typedef struct iso_scene_actuators {
    int enabled;
    int link;                      /* iso_scene_link_kind */
    char path[ISO_SCENE_PATH_MAX]; /* TTY device or serial port name */
    char host[ISO_SCENE_NAME_MAX];
    int port;
    int baud;      /* default the bridge board's rate, ISO_FB_BOARD_BAUD (115200) */
    int emulation; /* EMULATED: iso_scene_emu_mode */
    int vid, pid;  /* USB: the device's ids */
    iso_scene_channel ch[ISO_SCENE_MAX_CHANNELS];
    int n_ch;
    int loop_timeout_ms; /* loop watchdog bound; 0 (default) = max(250, 5 tick periods) */
} iso_scene_actuators;

/* ---- the scene -------------------------------------------------------------- */
typedef struct iso_scene {
    char path[ISO_SCENE_PATH_MAX]; /* the scene file */
    char dir[ISO_SCENE_PATH_MAX];  /* its folder: relative names start here */
    char name[ISO_SCENE_NAME_MAX]; /* `name:`, or the file's base name */

    iso_scene_mesh_src mesh_src;
    char sel[ISO_SCENE_PATH_MAX]; /* regions.sel: a .sel file, "builtin", or "" */
    int sel_line, sel_col;
    iso_scene_region fixed;
    iso_scene_handle handles[ISO_SCENE_MAX_HANDLES];
    int n_handles;

    iso_solver_opts solver;       /* cl_device is NULL */
    iso_integrate_opts integrate; /* restore_kappa (< 0: the ABM mode's default) */
    int steps_per_tick;           /* ABM steps per tick, default 1 */
    int abm_mode;                 /* iso_abm_mode: `abm: pece` (default) or `pec` */
    double tick_hz;               /* > 0, default 60 */

    iso_scene_device devices[ISO_SCENE_MAX_DEVICES];
    int n_devices;

    iso_scene_display display;
    iso_scene_ply ply;
    iso_scene_actuators actuators;
    char recording[ISO_SCENE_PATH_MAX]; /* "" = none */

    /* Built by iso_scene_load (not with ISO_SCENE_PARSE_ONLY). Owned. */
    iso_mesh *mesh;
    iso_regions regions; /* per-vertex kind and handle index */
    double shape_M[16];  /* the built-in shape's or benchmark's final transform */
    int have_shape_M;
} iso_scene;

/* Finds benchmark problem `name`: returns 1 and fills mesh, sel and def
 * (ISO_SCENE_PATH_MAX each), or 0 with where it looked in why. The command
 * passes its own lookup (controller/cli_args.c), so scenes resolve the
 * benchmark exactly like --benchmark does. */
typedef int (*iso_scene_bench_fn)(void *ctx, const char *name, char *mesh, char *sel, char *def,
                                  char *why, size_t why_cap);

enum { ISO_SCENE_PARSE_ONLY = 1 }; /* flags: read and validate the YAML, load no file */

typedef struct iso_scene_opts {
    iso_scene_bench_fn bench_find; /* NULL: benchmarks are absent (fallbacks stand in) */
    void *bench_ctx;
    unsigned flags;
} iso_scene_opts;

/* Loads and validates the scene at `path`. On success returns ISO_OK and a
 * new scene in *out (iso_scene_destroy frees it); on failure a negative
 * ISO_E* code, *out NULL and err filled ("FILE:LINE:COL: KEY: ..."). */
ISO_API ISO_NODISCARD int iso_scene_load(const char *path, iso_scene **out, iso_err *err);
ISO_API ISO_NODISCARD int iso_scene_load_opts(const char *path, const iso_scene_opts *opts,
                                              iso_scene **out, iso_err *err);
/* The same from text in memory; `name` is the file name used in messages
 * and for relative paths. */
ISO_API ISO_NODISCARD int iso_scene_load_mem(const char *text, size_t len, const char *name,
                                             const iso_scene_opts *opts, iso_scene **out,
                                             iso_err *err);
ISO_API void iso_scene_destroy(iso_scene *s); /* NULL is a no-op */

/* The stale time in ms the device d's source of kind source_kind
 * (ISO_DEV_KIND_*; in a replay, the recorded source's) gets: d's
 * stale_ms when the scene gives it, else ISO_SCENE_STALE_MS_VIEW_DEFAULT
 * for a view and ISO_SCENE_STALE_MS_DEFAULT for any other. */
ISO_API int iso_scene_device_stale_ms(const iso_scene_device *d, int source_kind);

/* The scene's actuators as the actuator sink takes them
 * (iso_actuators_create): its a->n_ch channels into out, and its link. */
ISO_API void iso_scene_actuator_channels(const iso_scene_actuators *a, iso_act_channel *out);
ISO_API void iso_scene_actuator_link(const iso_scene_actuators *a, iso_act_link_spec *out);

/* Names used in the schema, for summaries. Never NULL. */
ISO_API const char *iso_scene_driver_name(int kind);
ISO_API const char *iso_scene_backend_name(int backend);
ISO_API const char *iso_scene_link_name(int link);

#endif
