/* view/iso_display.h -- the live 3D view: a small HTTP + WebSocket server of
 * the display's own that serves a three.js page, streams vertex positions,
 * and, when the scene has a `view` device, takes the page's commands.
 *
 * The real-time loop owns an iso_display and calls iso_display_publish()
 * once per tick. Publishing copies the positions into a "latest frame" slot
 * under a lock held only for that copy and returns. One server thread of the
 * display's own does all the network I/O on non-blocking sockets; it never
 * holds that lock across a socket call, and nothing the loop calls waits on
 * it. Each browser ("viewer") has a queue of one frame where the latest
 * wins: a browser that reads slowly skips frames, never delays the others.
 *
 * Limits, each a stated bound:
 *   - ISO_DISPLAY_MAX_VIEWERS WebSockets at once; one more is answered 503
 *     at once and closed. Page requests have slots of their own beyond those,
 *     so the page loads with every viewer connected.
 *   - A viewer whose current frame or control message is not completely
 *     written ISO_DISPLAY_STALL_MS after it was queued is disconnected; so
 *     is one whose topology (tens of megabytes at a million vertices), or
 *     an HTTP response, makes no progress that long.
 *   - A request's line and headers must arrive whole within
 *     ISO_DISPLAY_REQUEST_TIMEOUT_MS and fit ISO_DISPLAY_MAX_REQUEST bytes
 *     (else the connection is closed, or answered 431).
 *   - A browser's messages are kept only up to ISO_DISPLAY_MAX_CLIENT_MESSAGE
 *     bytes (fragments together); a frame that would go beyond closes the
 *     connection (status 1009) before its payload is read. Memory per
 *     connection is fixed: the request buffer, that message buffer and, for
 *     a viewer, one frame; the kernel's send buffer of a viewer is bounded
 *     too (two frames, at least 64 KiB).
 *   - iso_display_destroy() returns within one pass of the server's loop
 *     (milliseconds; at most ISO_DISPLAY_POLL_MS after the wake if that were
 *     lost), whatever the browsers do.
 *
 * Under a flood of connections (a local process opening thousands a second)
 * page loads still get through; the policy, in the order it acts:
 *   1. the listen backlog is the system's maximum (somaxconn), and
 *      TCP_DEFER_ACCEPT hands the server only connections that have sent
 *      something, so connections that never send are not even seen;
 *   2. the server reads a connection's request the moment it accepts it
 *      (a browser's request is there by then), and answers it at once;
 *   3. it accepts at most ISO_DISPLAY_ACCEPT_BATCH connections between two
 *      passes over the ones it holds (accept fairness: a flood cannot keep
 *      it from writing the answers it owes);
 *   4. when every slot is taken, a newcomer takes the slot of the request
 *      that has shown the least: one with no byte yet first, then one
 *      lingering after its answer, then the oldest partial request; never
 *      a response being written or a viewer.
 * Every connection the server drops (a stalled viewer, an evicted or timed
 * out request) is closed at once with a reset, so what it had not yet sent
 * does not stay in the kernel's memory (tests/tools/view_tcp_memory: with a
 * viewer that never reads arriving every 100 ms for 45 s, the kernel's TCP
 * memory stays flat at 6-9 MiB, no orphans, where a close without the reset
 * let it grow by 143 MB); a connection it closes after a protocol error gets
 * its close frame and then the close.
 *
 * WebSocket (RFC 6455): a frame with reserved bits, a reserved opcode, no
 * mask, a long or fragmented control frame, a continuation without a start
 * or a new message inside a fragmented one closes with 1002; text that is
 * not UTF-8 (in a message or a close reason) with 1007; a close frame with a
 * status that may not be sent (999, 1004-1006, 1015, 1016-2999, >= 5000) or
 * a one-byte payload is answered with 1002, a valid one with its own status;
 * pings are answered with pongs.
 *
 * Who may connect: the server binds one address, loopback unless
 * opts.allow_remote. Every request's Host must name this view: localhost,
 * 127.0.0.1, [::1], the bound address or the address the connection arrived
 * on, with the view's port or none; otherwise 403 (so DNS rebinding gets
 * nowhere). A WebSocket upgrade that carries an Origin must come from the
 * page's own origin, http://NAME:PORT with NAME one of those; otherwise 403
 * (so other web pages cannot open the stream). Only GET and HEAD are served
 * (HEAD without a body); other methods get 405.
 *
 * Who may command (opts.view_device set): any WebSocket that passed those
 * checks, and, when the view listens beyond loopback (allow_remote), only
 * one whose /ws URL carries ?token=T with the token the display made at
 * create (iso_display_token; 128 random bits, printed with the URL so the
 * page gets it as a notebook server's does). Watching needs no token.
 * Commands (iso_dev_view.h): one viewer at a time is in control, the
 * first to send TAKE; it alone may send TARGETs and RELEASE; STOP comes
 * from any viewer that may command (a stop button must work for everyone
 * watching) and acts at once; UNSTOP only from the
 * viewer who pressed the stop or the one in control (any viewer that may
 * command once the one who pressed it has gone: a page that reconnects
 * must be able to release its own stop), and not within
 * ISO_DISPLAY_UNSTOP_MIN_MS of the stop (a page flapping its stop makes
 * at most four stops a second; STOP itself is never delayed). A repeated
 * STOP, or an UNSTOP with no stop pressed, is no change and does not reach
 * the device. What is refused is counted (iso_display_command_stats) and
 * never reaches the device; what
 * is accepted is queued on the device (iso_dev_view_push) in an envelope
 * naming the connection. A controller that disconnects ends its control
 * (ISO_DEV_VIEW_END_LEFT); so does iso_display_end(), and so does a
 * controller that sends no command for ISO_DISPLAY_LAPSE_MS
 * (ISO_DEV_VIEW_END_LAPSED): a hung or throttled tab cannot keep control
 * from another viewer, while a page in control sends its target every
 * 25 ms and a background tab's timers still run once a second.
 *
 * Pages served (from memory, except three.js):
 *   /, /index.html       the viewer (HTML)
 *   /app.js              the viewer's script
 *   /three.min.js        read at create time from Debian's libjs-three
 *   /OrbitControls.js    from libjs-three's examples when installed (the
 *   /TransformControls.js  page falls back to its own controls otherwise)
 *   /GLTFExporter.js     from libjs-three's examples: the page's "Save .glb"
 *   /ws                  the WebSocket (query: token=T)
 *
 * A client that offers the subprotocol "foxglove.websocket.v1" on /ws, once
 * iso_display_foxglove has made the session, gets Foxglove's protocol
 * instead (below); its Origin may also be Foxglove's web app.
 *
 * Wire format on /ws, server to browser:
 *   on connect, one binary message, the topology, little endian (binary
 *   because a million vertices made 84 MB of JSON, seconds to print and
 *   to parse before the first frame):
 *     offset  0  u32  ISO_DISPLAY_TOPOLOGY_MAGIC ("ISOT")
 *             4  u32  N, the vertex count
 *             8  u32  T, the triangle count
 *            12  u32  J, the bytes of the JSON that follows (a multiple of 4:
 *                     padded with spaces)
 *            16  J    UTF-8 JSON: {"type":"topology","nv":N,"nt":T,
 *                     "strain_full":0.1,"nh":H,"control":null or
 *                     {"handles":[{"name":S,"handle":h,"centre":[x,y,z]}...],
 *                     "token":true|false}}
 *          16+J  f32  rest positions, 3N
 *       16+J+12N u32  triangles' vertex indices, 3T
 *   16+J+12N+12T u8   each vertex's kind, N: 0 fixed, 1 free, 2 handle
 *   then, whenever it changes for that viewer, one text message
 *     {"type":"control","you":ID,"may_command":B,"holder":ID or 0,
 *      "stop":B,"ended":B,"refused":N,"why":S}
 *   and {"type":"note","text":S} for what iso_display_end() says;
 *   then, per published tick, one binary message, little endian:
 *     offset  0  u32  ISO_DISPLAY_FRAME_MAGIC ("ISOF")
 *             4  u32  N, the vertex count
 *             8  f64  tick number
 *            16  f32  tick compute time median, ms
 *            20  f32  tick compute time p99, ms
 *            24  f32  tick compute time max, ms
 *            28  f32  input-to-publish latency, ms
 *            32  u32  deadlines missed: passed without a tick of their own, however
 *                 the loop was held (saturated at 2^32-1)
 *            36  u32  H, the handle poses that follow the header
 *            40  u32  the connection whose command the tick applied last
 *            44  u32  that command's sequence number (0: none yet)
 *            48  f64  that command's page clock, ms, as the page sent it
 *            56  u32  flags: ISO_DISPLAY_FLAG_*
 *            60  u32  reserved, 0
 *            64  7H f64  each handle's pose rest -> current: position, then
 *                    the rotation's unit quaternion x y z w
 *        64+56H  f32  positions, 3N
 *
 * Browser to server on /ws: the commands (binary, iso_dev_view.h), and, as
 * the page takes each frame in (its onmessage), the text message
 * {"type":"took","tick":T} with that frame's tick number T. A viewer that
 * has sent one is paced from then on: it is sent the newest frame only
 * once it took the last frame it was sent, so at most one frame is on its
 * way to it (in the sockets' buffers or the browser's queue) and what it
 * shows is at most that one behind the loop. A viewer that never sends one
 * is sent the newest frame whenever the last is written, and one that
 * reads slowly lags by what the kernel's buffers hold (a few frames).
 * Either way the loop never waits. */
#ifndef ISO_DISPLAY_H
#define ISO_DISPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev_view.h"
#include "iso_err.h"
#include "iso_geom.h"
#include "iso_mesh.h"
#include "iso_regions.h"

#define ISO_DISPLAY_FRAME_MAGIC 0x464f5349u /* "ISOF" read as little endian */
#define ISO_DISPLAY_FRAME_HEADER 64
#define ISO_DISPLAY_TOPOLOGY_MAGIC 0x544f5349u /* "ISOT" read as little endian */
#define ISO_DISPLAY_TOPOLOGY_HEADER 16
#define ISO_DISPLAY_FRAME_POSE 56 /* bytes per handle pose: 7 f64 */
#define ISO_DISPLAY_MAX_HANDLES 8
#define ISO_DISPLAY_TOOK_PREFIX "{\"type\":\"took\",\"tick\":" /* then T, then } */
#define ISO_DISPLAY_DEFAULT_HOST "127.0.0.1"
#define ISO_DISPLAY_DEFAULT_THREE "/usr/share/javascript/three/three.min.js"

/* Frame flags: what the tick's commands were. */
#define ISO_DISPLAY_FLAG_ESTOP 1u     /* an e-stop (any source) held the handles */
#define ISO_DISPLAY_FLAG_TARGETING 2u /* the view device's target drove a handle */
#define ISO_DISPLAY_FLAG_STALE 4u     /* the view device's controller went quiet */
#define ISO_DISPLAY_FLAG_HOLDER 8u    /* the view device's stream has a controller */

#define ISO_DISPLAY_MAX_VIEWERS 16          /* WebSockets at once; one more gets 503 */
#define ISO_DISPLAY_MAX_CONNS 64            /* all connections, viewers included */
#define ISO_DISPLAY_ACCEPT_BATCH 64         /* accepts between two passes over the table */
#define ISO_DISPLAY_STALL_MS 2000           /* a message unwritten this long drops the peer */
#define ISO_DISPLAY_REQUEST_TIMEOUT_MS 5000 /* request line and headers, whole */
#define ISO_DISPLAY_MAX_REQUEST 8192        /* bytes of request line and headers */
#define ISO_DISPLAY_MAX_CLIENT_MESSAGE 4096 /* largest message taken from a browser */
#define ISO_DISPLAY_POLL_MS 250             /* the server's longest sleep */
#define ISO_DISPLAY_TURN_BYTES (256 * 1024) /* written to one connection in one poll turn */
#define ISO_DISPLAY_UNSTOP_MIN_MS 250       /* a stop stays pressed at least this long */
#define ISO_DISPLAY_LAPSE_MS 3000           /* a silent holder's control ends after this */

typedef struct iso_display iso_display; /* opaque */

/* Receives one line of notice (no newline), e.g. the warning that the view
 * listens beyond this machine. NULL in the options prints it to stderr. */
typedef void (*iso_display_notice_fn)(void *ctx, const char *line);

/* A handle the page may command: the view device's handle index j (the
 * mapping's) is the j-th entry. */
typedef struct iso_display_handle {
    const char *name; /* as the scene names it; copied */
    int handle;       /* the mesh's handle (regions) it moves */
} iso_display_handle;

typedef struct iso_display_opts {
    const char *host;             /* numeric IPv4 or IPv6 address (brackets allowed) or
                                     "localhost"; NULL = "127.0.0.1" (localhost only) */
    int port;                     /* TCP port; 0 = any free port (see iso_display_port) */
    const iso_mesh *mesh;         /* topology and rest pose; must outlive the display */
    const iso_regions *regions;   /* fixed/handle marks, copied; NULL = all free */
    const char *three_js;         /* three.min.js path; NULL = ISO_DISPLAY_DEFAULT_THREE */
    int allow_remote;             /* non-zero: a host other than loopback (0.0.0.0, ::, a LAN
                                     address) may be bound, with a warning through notice;
                                     0 refuses it. Scene key: sinks.display.allow_remote */
    iso_display_notice_fn notice; /* NULL = stderr */
    void *notice_ctx;
    /* The page as a control surface: a source from iso_dev_view_open that
     * the page's accepted commands are queued on (it must outlive the
     * display), and the handles it may move (at most
     * ISO_DISPLAY_MAX_HANDLES). NULL: the page only watches, and says so. */
    iso_dev_source *view_device;
    const iso_display_handle *handles;
    int n_handles;
} iso_display_opts;

/* What the page shows beside the mesh; the loop fills what it has. Zero
 * is "nothing" for every field. */
typedef struct iso_display_stats {
    double tick_ms_median, tick_ms_p99, tick_ms_max; /* tick compute time */
    double latency_ms;                               /* input to publish */
    long misses; /* deadlines that passed without a tick of their own so far */
    /* The handles' poses, rest -> current, for the mesh's handles 0..n-1
     * (at most the regions' count and ISO_DISPLAY_MAX_HANDLES). */
    int n_handles;
    iso_pose handle[ISO_DISPLAY_MAX_HANDLES];
    /* The view device's last applied command (iso_dev_view_state). */
    uint32_t cmd_conn, cmd_seq;
    double cmd_page_ms;
    unsigned flags; /* ISO_DISPLAY_FLAG_* */
} iso_display_stats;

/* Commands the server took from pages, since create. */
typedef struct iso_display_command_stats {
    uint32_t accepted;  /* queued on the device */
    uint32_t refused;   /* well-formed but not permitted: read-only view, no token, not in
                           control, control taken, a handle the page may not move */
    uint32_t malformed; /* not a command (iso_dev_view_parse refused it) */
    uint32_t dropped;   /* permitted, but the device's queue was full */
    uint32_t grants;    /* times a viewer took control */
    uint32_t stops;     /* STOP messages taken */
} iso_display_command_stats;

/* Starts the server and its thread. On success returns ISO_OK and stores a
 * handle in *out (destroy with iso_display_destroy). Fails with ISO_EINVAL
 * (no mesh, bad port, regions of another size, a host that is not a numeric
 * address or localhost, a host beyond loopback without opts.allow_remote,
 * a view device that is not one, too many handles), ISO_EIO (three.js
 * missing or unreadable, naming the path and the package; the address
 * cannot be bound; no random token) or ISO_ENOMEM; *out is then NULL and
 * err says which. */
ISO_API ISO_NODISCARD int iso_display_create(const iso_display_opts *opts, iso_display **out,
                                             iso_err *err);

/* The TCP port actually bound (useful with opts.port = 0). */
ISO_API int iso_display_port(const iso_display *d);

/* The command token ("" when none is needed: loopback, or no view device):
 * 32 hex digits, for the page's URL as ?token=T. */
ISO_API const char *iso_display_token(const iso_display *d);

/* Writes the page's URL into buf: http://HOST:PORT/ with the token when
 * one is needed. Returns snprintf's result. */
ISO_API int iso_display_url(const iso_display *d, char *buf, size_t cap);

/* Number of browsers connected to /ws right now (0 for NULL). Takes no
 * lock: an atomic the server thread updates. */
ISO_API int iso_display_clients(const iso_display *d);

/* Number of published frames the server has written whole to at least one
 * browser (0 for NULL). Takes no lock. */
ISO_API long iso_display_frames_sent(const iso_display *d);

/* The command counters (zero for NULL); any thread, no lock. */
ISO_API void iso_display_command_stats_get(const iso_display *d, iso_display_command_stats *out);

/* The connection in control (0: none); any thread, no lock. */
ISO_API uint32_t iso_display_holder(const iso_display *d);

/* Hands the positions x (3*nv, as the mesh) of `tick` to the display and
 * returns at once: no network I/O, no allocation, one copy under a lock the
 * server holds only for a memcpy of its own, and at most one write of a byte
 * to a non-blocking pipe to wake the server. stats may be NULL. Returns
 * ISO_EINVAL for NULL d or x; non-finite positions are sent as they are.
 * What it costs is that copy: at 160k vertices 0.2-0.4 ms median, 1.25
 * ms at most with 0, 1 or 4 viewers, 1.2-2 times a memcpy of the frame; a
 * viewer can add at most the server's own copy of the frame out of the
 * slot (tests/tools/view_publish_bench; docs/performance.md, "The live
 * view at scale"). */
ISO_API int iso_display_publish(iso_display *d, long tick, const double *x,
                                const iso_display_stats *stats, iso_err *err);

/* The run is over: the page keeps showing the last frame, stops taking
 * commands (control ends, ISO_DEV_VIEW_END_STOPPED) and shows `text` (the
 * run's summary, or NULL for none), until the display is destroyed. Any
 * thread; takes a lock for the copy of text (at most 4 KiB are kept). */
ISO_API void iso_display_end(iso_display *d, const char *text);
/* Foxglove, live. After this call the view's server also speaks Foxglove's
 * WebSocket protocol on /ws to a client that offers the subprotocol
 * "foxglove.websocket.v1" (Foxglove Studio's "Open connection"): it
 * advertises the session's channels, the same as an MCAP export's
 * (sinks/iso_foxglove.h), and streams the ticks iso_display_publish_frame
 * hands it, under the page's rules: latest wins, nothing waits for a
 * client, a client whose batch is unwritten ISO_DISPLAY_STALL_MS is
 * disconnected, and it counts among ISO_DISPLAY_MAX_VIEWERS. Its Origin,
 * when it sends one, must be the page's own or Foxglove's web app
 * (https://app.foxglove.dev). The subprotocol is matched as a token of
 * the offer, to the letter; an offer of it before this call (a run's first
 * moments) gets 503 with Retry-After: 1. A subscription to a channel that
 * is not advertised, or an op that is not served, is answered with a
 * "status" message (level 1) saying which. s->mesh must be the
 * display's mesh.
 * Call it once, before the first publish. ISO_EINVAL, ISO_ENOMEM. */
struct iso_sink_session;
struct iso_sink_frame;
ISO_API ISO_NODISCARD int iso_display_foxglove(iso_display *d, const struct iso_sink_session *s,
                                               iso_err *err);

/* Hands the display the rest of a tick's channels (poses, devices, the
 * loop, actuators; f->x is ignored: the positions are those of the
 * iso_display_publish just before). A copy under the frame lock, no
 * allocation, no I/O. ISO_EINVAL for NULL arguments. */
ISO_API int iso_display_publish_frame(iso_display *d, const struct iso_sink_frame *f, iso_err *err);

/* Stops the server thread, closes every connection and frees everything.
 * Never waits on a browser: returns within one pass of the server's loop
 * even when a browser stopped reading. NULL is a no-op. */
ISO_API void iso_display_destroy(iso_display *d);

#endif
