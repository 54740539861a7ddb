/* sim/iso_display.h -- the live 3D view: an embedded HTTP + WebSocket server
 * (civetweb) that serves a three.js page and streams vertex positions.
 *
 * The real-time loop owns an iso_display and calls iso_display_publish()
 * once per tick. Publishing copies the positions into a "latest frame" slot
 * under a lock held only for that copy and returns; a sender thread of the
 * display's own takes the newest frame and writes it to every connected
 * browser. A slow or stalled browser therefore slows only the sender, never
 * the loop, and frames it could not keep up with are skipped, not queued.
 *
 * Pages served (from memory, except three.js):
 *   /                 the viewer (HTML)
 *   /app.js           the viewer's script
 *   /three.min.js     read at create time from Debian's libjs-three
 *   /OrbitControls.js from libjs-three's examples when installed (the page
 *                     falls back to its own small orbit control otherwise)
 *   /ws               the WebSocket
 *
 * Wire format on /ws (server to browser; the browser sends nothing):
 *   on connect, one text message, JSON:
 *     {"type":"topology","nv":N,"nt":T,"rest":[3N numbers],"tri":[3T ints],
 *      "kind":[N ints: 0 fixed, 1 free, 2 handle],"strain_full":0.1}
 *   then, per published tick, one binary message, little endian:
 *     offset  0  u32  ISO_DISPLAY_FRAME_MAGIC ("ISOF")
 *             4  u32  N, the vertex count
 *             8  f64  tick number
 *            16  f32  tick compute time median, ms
 *            20  f32  tick compute time p99, ms
 *            24  f32  tick compute time max, ms
 *            28  f32  input-to-publish latency, ms
 *            32  u32  deadline misses (saturated at 2^32-1)
 *            36  u32  reserved, 0
 *            40  f32  positions, 3N
 *
 * Built without civetweb, iso_display_create() returns ISO_ENOTSUP with a
 * sentence saying so; the headless outputs (iso_snapshot.h) do not need it. */
#ifndef ISO_DISPLAY_H
#define ISO_DISPLAY_H

#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_regions.h"

#define ISO_DISPLAY_FRAME_MAGIC 0x464f5349u /* "ISOF" read as little endian */
#define ISO_DISPLAY_FRAME_HEADER 40
#define ISO_DISPLAY_DEFAULT_HOST "127.0.0.1"
#define ISO_DISPLAY_DEFAULT_THREE "/usr/share/javascript/three/three.min.js"

typedef struct iso_display iso_display; /* opaque */

typedef struct iso_display_opts {
    const char *host;           /* address to bind; NULL = "127.0.0.1" (localhost only) */
    int port;                   /* TCP port; 0 = any free port (see iso_display_port) */
    const iso_mesh *mesh;       /* topology and rest pose; must outlive the display */
    const iso_regions *regions; /* fixed/handle marks, copied; NULL = all free */
    const char *three_js;       /* three.min.js path; NULL = ISO_DISPLAY_DEFAULT_THREE */
} iso_display_opts;

/* What the page shows beside the mesh; the loop fills what it has. */
typedef struct iso_display_stats {
    double tick_ms_median, tick_ms_p99, tick_ms_max; /* tick compute time */
    double latency_ms;                               /* input to publish */
    long misses;                                     /* deadline misses so far */
} iso_display_stats;

/* Starts the server and its sender thread. On success returns ISO_OK and
 * stores a handle in *out (destroy with iso_display_destroy). Fails with
 * ISO_EINVAL (no mesh, bad port, regions of another size), ISO_EIO (three.js
 * missing or unreadable, naming the path and the package; the address cannot
 * be bound), ISO_ENOTSUP (built without civetweb) or ISO_ENOMEM; *out is then
 * NULL and err says which. */
ISO_NODISCARD int iso_display_create(const iso_display_opts *opts, iso_display **out, iso_err *err);

/* The TCP port actually bound (useful with opts.port = 0). */
int iso_display_port(const iso_display *d);

/* Number of browsers connected to /ws right now (0 for NULL). */
int iso_display_clients(const iso_display *d);

/* Number of frames the sender thread has written to at least one browser
 * (0 for NULL). */
long iso_display_frames_sent(const iso_display *d);

/* Hands the positions x (3*nv, as the mesh) of `tick` to the display and
 * returns at once: no network I/O, no allocation, one memcpy under a lock
 * other holders keep only for a memcpy of their own. stats may be NULL. Returns
 * ISO_EINVAL for NULL d or x; non-finite positions are sent as they are. */
int iso_display_publish(iso_display *d, long tick, const double *x, const iso_display_stats *stats,
                        iso_err *err);

/* Stops the server (closing browser connections) and the sender thread,
 * then frees everything. With a browser that stopped reading, this waits
 * for civetweb's write and shutdown timeouts (a few seconds). NULL is a no-op. */
void iso_display_destroy(iso_display *d);

#endif
