/* config/scene.c -- reading a scene file (YAML, libfyaml) into iso_scene:
 * the document and its top level.
 *
 * The sections each have a file and a table of keys (internal.h): mesh
 * (scene_mesh.c), regions, handles and selections (scene_regions.c), the
 * handles' drivers and device mappings (scene_drivers.c), solver and
 * integrator (scene_solver.c), devices (scene_devices.c), and the sinks
 * (scene_sinks.c). scene_walk.c reads a mapping by its table. libfyaml's
 * own diagnostics are collected, never printed, and the first one becomes
 * the error. */
#include "internal.h"

#include <libfyaml.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "iso_file.h"
#include "iso_names.h"

/* ------------------------------------------------------------------------ */
/* The top level                                                             */
/* ------------------------------------------------------------------------ */

/* Devices come before regions: drivers name them. */
static const scene_key top_keys[] = {
    {"name", SK_STRING, FIELD(iso_scene, name), .help = "a label for summaries",
     .dflt = "the file's base name"},
    {"mesh", SK_SECTION, FIELD(iso_scene, mesh_src), SK_REQUIRED, .sub = &iso_scene__mesh,
     .type = "file or mapping", .help = "a mesh file, {shape: NAME} or {benchmark: NAME}"},
    {"devices", SK_LIST, FIELD(iso_scene, devices), .count_off = offsetof(iso_scene, n_devices),
     .stride = sizeof(iso_scene_device), .max_items = ISO_SCENE_MAX_DEVICES,
     .sub = &iso_scene__device, .noun = "devices", .type = "list of devices",
     .help = "the input devices, each {name, kind, ...}", .dflt = "none"},
    {"regions", SK_SECTION, 0, 0, SK_REQUIRED, .sub = &iso_scene__regions,
     .help = "a mapping with sel, fixed and handles"},
    {"solver", SK_SECTION, FIELD(iso_scene, solver), .sub = &iso_scene__solver,
     .help = "the solver's settings"},
    {"integrator", SK_SECTION, 0, 0, .sub = &iso_scene__integrator,
     .help = "the integrator's settings"},
    {"tick_hz", SK_NUMBER, FIELD(iso_scene, tick_hz), IN_OC(0, 100000),
     .help = "the loop's rate in Hz", .dflt = "60"},
    {"sinks", SK_SECTION, 0, 0, .sub = &iso_scene__sinks,
     .help = "where the shape goes: display, ply, actuators", .dflt = "none"},
    {"recording", SK_PATH, FIELD(iso_scene, recording),
     .help = "a .isorec file to record the devices to (a `record` button's later recordings: "
             "NAME-2.EXT, NAME-3.EXT, ...)",
     .dflt = "none"},
    {.key = NULL},
};

const scene_section iso_scene__schema = {
    .name = "", .what = "a mapping with mesh and regions", .keys = top_keys};

/* SCENES.md forbids anchors and aliases: a scene says each value where it
 * applies. Walks the whole document first, so an anchor that nothing uses
 * is refused too, and an alias is named as one rather than as the value it
 * stands for. Deeper than any scene goes, the schema walk refuses it. */
static int no_anchors(scene_ctx *c, fnode *n, const char *path, int depth);

static int no_anchors_in(scene_ctx *c, fnode *n, const char *path, int depth)
{
    void *it = NULL;
    char key[ISO_SCENE_KEY_MAX];
    int rc = ISO_OK;
    if (fy_node_is_mapping(n)) {
        struct fy_node_pair *p;
        while (rc == ISO_OK && (p = fy_node_mapping_iterate(n, &it)) != NULL) {
            const char *ks = iso_scene__scalar(c, fy_node_pair_key(p));
            iso_scene__join(key, sizeof key, path, ks ? ks : "?");
            rc = no_anchors(c, fy_node_pair_key(p), key, depth + 1);
            if (rc == ISO_OK)
                rc = no_anchors(c, fy_node_pair_value(p), key, depth + 1);
        }
    } else if (fy_node_is_sequence(n)) {
        fnode *item;
        for (int i = 0; rc == ISO_OK && (item = fy_node_sequence_iterate(n, &it)) != NULL; i++) {
            snprintf(key, sizeof key, "%s[%d]", path, i);
            rc = no_anchors(c, item, key, depth + 1);
        }
    }
    return rc;
}

static int no_anchors(scene_ctx *c, fnode *n, const char *path, int depth)
{
    const char *at = path && *path ? path : "(top level)";
    size_t len = 0;
    struct fy_anchor *a = n ? fy_node_get_anchor(n) : NULL;
    if (a) {
        const char *t = fy_anchor_get_text(a, &len);
        return iso_scene__fail(
            c, n, ISO_EPARSE, at,
            "anchors ('&%.*s') are not accepted in scene files; write the value out",
            (int)(t ? len : 0), t ? t : "");
    }
    if (n && fy_node_is_alias(n)) {
        const char *t = fy_node_get_scalar(n, &len);
        return iso_scene__fail(
            c, n, ISO_EPARSE, at,
            "aliases ('*%.*s') are not accepted in scene files; write the value out",
            (int)(t ? len : 0), t ? t : "");
    }
    if (!n || depth > 64)
        return ISO_OK;
    return no_anchors_in(c, n, path, depth);
}

static int parse_root(scene_ctx *c, fnode *root)
{
    int rc;
    if (!root)
        return iso_err_set(c->err, ISO_EPARSE, 1,
                           "%s:1:1: (top level): the file is empty "
                           "(expected a mapping with mesh and regions)",
                           c->file);
    if ((rc = no_anchors(c, root, "", 0)) ||
        (rc = iso_scene__want_map(c, root, "(top level)", iso_scene__schema.what)))
        return rc;
    return iso_scene__walk(c, &iso_scene__schema, root, "", c->s, -1, 0);
}

/* ------------------------------------------------------------------------ */
/* The document                                                              */
/* ------------------------------------------------------------------------ */

/* libfyaml's diagnostics go here instead of stderr; the collected errors
 * are read back after a failed parse. */
static void diag_sink(struct fy_diag *diag, void *user, const char *buf, size_t len)
{
    (void)diag;
    (void)user;
    (void)buf;
    (void)len;
}

/* A scene before its file is read: names from its path, and the defaults
 * of whatever the file may leave out. */
static iso_scene *new_scene(const char *path)
{
    iso_scene *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    snprintf(s->path, sizeof s->path, "%s", path);
    const char *slash = strrchr(path, '/');
    if (slash)
        snprintf(s->dir, sizeof s->dir, "%.*s", (int)(slash - path == 0 ? 1 : slash - path), path);
    const char *base = slash ? slash + 1 : path;
    snprintf(s->name, sizeof s->name, "%.*s", (int)strcspn(base, "."), base);
    iso_solver_opts_default(&s->solver);
    /* A scene that names no solver settings gets the fast path for its
     * size, not the library's paper-faithful always-refactor scheme: the
     * cached factor as PCG's preconditioner, factored on a worker four
     * ticks ahead, OpenCL where a GPU is. On the built-in plane of 2,601
     * vertices the library's defaults ticked at 13.8-18.6 ms, these at
     * 7.7-9.7 ms (same run). And a mesh too large for the method to step
     * within the tick runs on the reduced model (proxy auto): the whole
     * 40k plane ticks 2-4 times a second and a 160k mesh takes gigabytes
     * and seconds a tick, where the reduced model ticks at 60 Hz. It is the
     * method at the proxy's resolution, not at the mesh's (docs/method.md
     * says what that costs in distortion); the run says so when it starts,
     * and `proxy: off` asks for the whole mesh. */
    s->solver.refactor = ISO_REFACTOR_ADAPTIVE;
    s->solver.worker_lag = 4;
    s->solver.assembly = ISO_ASSEMBLY_AUTO;
    s->solver.proxy = ISO_SOLVER_PROXY_AUTO;
    iso_integrate_opts_default(&s->integrate);
    s->integrate.restore_kappa = -1; /* the ABM mode's own */
    s->steps_per_tick = 1;
    s->abm_mode = ISO_ABM_PECE;
    s->tick_hz = 60;
    snprintf(s->display.host, sizeof s->display.host, "127.0.0.1");
    s->display.port = 8080;
    return s;
}

static int blank(const char *text, size_t len, size_t i)
{
    return i >= len || text[i] == ' ' || text[i] == '\t' || text[i] == '\n' || text[i] == '\r';
}

/* The column (from 1) of a block explicit key ('?' and a blank, after the
 * indentation and any sequence dashes) that opens the line at text[i], or 0. */
static size_t explicit_key(const char *text, size_t len, size_t i)
{
    size_t j = i;
    for (;;) {
        while (j < len && (text[j] == ' ' || text[j] == '\t'))
            j++;
        if (j < len && text[j] == '-' && j + 1 < len && blank(text, len, j + 1) &&
            text[j + 1] != '\n' && text[j + 1] != '\r')
            j++;
        else
            break;
    }
    return j < len && text[j] == '?' && blank(text, len, j + 1) ? j - i + 1 : 0;
}

/* libfyaml 0.7.12 can loop forever scanning a malformed directive, and
 * crashes on a block explicit key whose value holds a tab before an
 * indicator ("? e:\t-"; both found by fuzz_scene). Scenes have no use for
 * either: refuses a line that starts with '%' or opens with "? ", and
 * control bytes, before the parser sees them. */
static int plain_text(const char *text, size_t len, const char *path, iso_err *err)
{
    for (size_t i = 0, line = 1, col; i < len; i++) {
        unsigned char ch = (unsigned char)text[i];
        int starts = i == 0 || text[i - 1] == '\n' || text[i - 1] == '\r';
        if (ch < 0x20 && ch != '\t' && ch != '\n' && ch != '\r')
            return iso_err_set(err, ISO_EPARSE, (long)line,
                               "%s:%zu: control byte 0x%02x: a scene is a text file", path, line,
                               ch);
        if (starts && ch == '%')
            return iso_err_set(err, ISO_EPARSE, (long)line,
                               "%s:%zu:1: YAML directives ('%%...') are not supported in "
                               "scene files",
                               path, line);
        if (starts && (col = explicit_key(text, len, i)) > 0)
            return iso_err_set(err, ISO_EPARSE, (long)line,
                               "%s:%zu:%zu: explicit keys ('? ') are not supported in scene "
                               "files; write KEY: VALUE",
                               path, line, col);
        line += text[i] == '\n';
    }
    return ISO_OK;
}

/* The first error libfyaml collected, as ours. */
static int syntax_error(struct fy_diag *diag, const char *path, iso_err *err)
{
    void *it = NULL;
    struct fy_diag_error *e = fy_diag_errors_iterate(diag, &it);
    /* libfyaml's collected line and column count from 1 already. */
    if (e)
        return iso_err_set(err, ISO_EPARSE, e->line, "%s:%d:%d: YAML syntax error: %s", path,
                           e->line > 0 ? e->line : 1, e->column > 0 ? e->column : 1,
                           e->msg ? e->msg : "?");
    return iso_err_set(err, ISO_EPARSE, 1,
                       "%s:1:1: (top level): the file is empty or holds "
                       "no YAML document (expected a mapping with mesh and regions)",
                       path);
}

/* Parses the text and walks it into s. */
static int read_document(iso_scene *s, const char *text, size_t len, const char *path,
                         unsigned flags, iso_err *err)
{
    struct fy_diag_cfg dcfg;
    fy_diag_cfg_default(&dcfg);
    dcfg.fp = NULL;
    dcfg.output_fn = diag_sink;
    dcfg.colorize = false;
    struct fy_diag *diag = fy_diag_create(&dcfg);
    if (!diag)
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: cannot create the YAML diagnostics", path);
    fy_diag_set_collect_errors(diag, true);
    struct fy_parse_cfg cfg = {.flags = FYPCF_QUIET | FYPCF_COLLECT_DIAG, .diag = diag};
    struct fy_document *doc = fy_document_build_from_string(&cfg, text, len);
    scene_ctx *c = doc ? calloc(1, sizeof *c) : NULL;
    int rc;
    if (!doc) {
        rc = syntax_error(diag, path, err);
    } else if (!c) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    } else {
        *c = (scene_ctx){.s = s, .file = path, .err = err};
        c->check_files = !(flags & ISO_SCENE_PARSE_ONLY);
        rc = parse_root(c, fy_document_root(doc));
    }
    free(c);
    fy_document_destroy(doc);
    fy_diag_destroy(diag);
    return rc;
}

static int load(const char *text, size_t len, const char *path, const iso_scene_opts *opts,
                iso_scene **out, iso_err *err)
{
    *out = NULL;
    iso_scene_opts o0 = {0};
    if (!opts)
        opts = &o0;
    iso_scene *s = new_scene(path);
    if (!s)
        return iso_err_set(err, ISO_ENOMEM, -1, "out of memory");
    int rc = ISO_OK;
    char *owned = NULL;
    if (!text) {
        iso_err fe;
        iso_err_clear(&fe);
        if ((rc = iso_file_read(path, 16u << 20, &owned, &len, &fe)) != ISO_OK)
            rc = iso_err_set(err, rc, fe.offset, "%s%s", fe.msg,
                             rc == ISO_EINVAL ? " (16 MiB): not a scene" : "");
        text = owned;
    }
    if (rc == ISO_OK)
        rc = plain_text(text, len, path, err);
    if (rc == ISO_OK)
        rc = read_document(s, text, len, path, opts->flags, err);
    if (rc == ISO_OK && !(opts->flags & ISO_SCENE_PARSE_ONLY))
        rc = iso_scene__build(s, opts, err);
    free(owned);
    if (rc != ISO_OK) {
        iso_scene_destroy(s);
        return rc;
    }
    *out = s;
    return ISO_OK;
}

int iso_scene_load_opts(const char *path, const iso_scene_opts *opts, iso_scene **out, iso_err *err)
{
    return load(NULL, 0, path, opts, out, err);
}

int iso_scene_load(const char *path, iso_scene **out, iso_err *err)
{
    return load(NULL, 0, path, NULL, out, err);
}

int iso_scene_load_mem(const char *text, size_t len, const char *name, const iso_scene_opts *opts,
                       iso_scene **out, iso_err *err)
{
    return load(text ? text : "", text ? len : 0, name, opts, out, err);
}

void iso_scene_destroy(iso_scene *s)
{
    if (!s)
        return;
    for (int i = 0; i < s->fixed.n_sel; i++)
        free(s->fixed.sel[i].vertices);
    for (int h = 0; h < ISO_SCENE_MAX_HANDLES; h++)
        for (int i = 0; i < s->handles[h].region.n_sel; i++)
            free(s->handles[h].region.sel[i].vertices);
    iso_mesh_destroy(s->mesh);
    iso_regions_deinit(&s->regions);
    free(s);
}

const char *iso_scene_driver_name(int kind)
{
    static const char *const names[] = {"none", "device", "screw", "keyframes", NULL};
    return iso_names_get(names, kind);
}

const char *iso_scene_link_name(int link)
{
    static const char *const names[] = {"?", "tty", "tcp", "serial", "emulated", "usb", NULL};
    return iso_names_get(names, link);
}
