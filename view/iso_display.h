/* view/iso_display.h -- the live 3D view: a small HTTP + WebSocket server of
 * the display's own that serves a three.js page and streams vertex positions.
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
 *   - A viewer whose current message (one frame, or the topology on connect)
 *     is not completely written ISO_DISPLAY_STALL_MS after it was queued is
 *     disconnected; so is an HTTP response that makes no progress that long.
 *   - A request's line and headers must arrive whole within
 *     ISO_DISPLAY_REQUEST_TIMEOUT_MS and fit ISO_DISPLAY_MAX_REQUEST bytes
 *     (else the connection is closed, or answered 431). When every slot is
 *     taken, a new connection replaces the oldest one still sending its
 *     request.
 *   - A browser's frames are parsed and thrown away, never buffered; one
 *     announcing more than ISO_DISPLAY_MAX_CLIENT_FRAME bytes closes the
 *     connection (status 1009) before its payload is read. Memory per
 *     connection is fixed: the request buffer and, for a viewer, one frame.
 *   - iso_display_destroy() returns within one pass of the server's loop
 *     (milliseconds; at most ISO_DISPLAY_POLL_MS after the wake if that were
 *     lost), whatever the browsers do.
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
 * Pages served (from memory, except three.js):
 *   /, /index.html    the viewer (HTML)
 *   /app.js           the viewer's script
 *   /three.min.js     read at create time from Debian's libjs-three
 *   /OrbitControls.js from libjs-three's examples when installed (the page
 *                     falls back to its own small orbit control otherwise)
 *   /GLTFExporter.js  from libjs-three's examples: the page's "Save .glb"
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
 *   A browser may send nothing but a close frame (or frames of at most
 *   ISO_DISPLAY_MAX_CLIENT_FRAME bytes, which are ignored); pings are not
 *   answered. */
#ifndef ISO_DISPLAY_H
#define ISO_DISPLAY_H

#include "iso_err.h"
#include "iso_mesh.h"
#include "iso_regions.h"

#define ISO_DISPLAY_FRAME_MAGIC 0x464f5349u /* "ISOF" read as little endian */
#define ISO_DISPLAY_FRAME_HEADER 40
#define ISO_DISPLAY_DEFAULT_HOST "127.0.0.1"
#define ISO_DISPLAY_DEFAULT_THREE "/usr/share/javascript/three/three.min.js"

#define ISO_DISPLAY_MAX_VIEWERS 16          /* WebSockets at once; one more gets 503 */
#define ISO_DISPLAY_MAX_CONNS 48            /* all connections, viewers included */
#define ISO_DISPLAY_STALL_MS 2000           /* a message unwritten this long drops the peer */
#define ISO_DISPLAY_REQUEST_TIMEOUT_MS 5000 /* request line and headers, whole */
#define ISO_DISPLAY_MAX_REQUEST 8192        /* bytes of request line and headers */
#define ISO_DISPLAY_MAX_CLIENT_FRAME 4096   /* largest frame payload taken from a browser */
#define ISO_DISPLAY_POLL_MS 250             /* the server's longest sleep */

typedef struct iso_display iso_display; /* opaque */

/* Receives one line of notice (no newline), e.g. the warning that the view
 * listens beyond this machine. NULL in the options prints it to stderr. */
typedef void (*iso_display_notice_fn)(void *ctx, const char *line);

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
} iso_display_opts;

/* What the page shows beside the mesh; the loop fills what it has. */
typedef struct iso_display_stats {
    double tick_ms_median, tick_ms_p99, tick_ms_max; /* tick compute time */
    double latency_ms;                               /* input to publish */
    long misses;                                     /* deadline misses so far */
} iso_display_stats;

/* Starts the server and its thread. On success returns ISO_OK and stores a
 * handle in *out (destroy with iso_display_destroy). Fails with ISO_EINVAL
 * (no mesh, bad port, regions of another size, a host that is not a numeric
 * address or localhost, a host beyond loopback without opts.allow_remote),
 * ISO_EIO (three.js missing or unreadable, naming the path and the package;
 * the address cannot be bound) or ISO_ENOMEM; *out is then NULL and err says
 * which. */
ISO_API ISO_NODISCARD int iso_display_create(const iso_display_opts *opts, iso_display **out,
                                             iso_err *err);

/* The TCP port actually bound (useful with opts.port = 0). */
ISO_API int iso_display_port(const iso_display *d);

/* Number of browsers connected to /ws right now (0 for NULL). Takes no
 * lock: an atomic the server thread updates. */
ISO_API int iso_display_clients(const iso_display *d);

/* Number of published frames the server has written whole to at least one
 * browser (0 for NULL). Takes no lock. */
ISO_API long iso_display_frames_sent(const iso_display *d);

/* Hands the positions x (3*nv, as the mesh) of `tick` to the display and
 * returns at once: no network I/O, no allocation, one copy under a lock the
 * server holds only for a memcpy of its own, and at most one write of a byte
 * to a non-blocking pipe to wake the server. stats may be NULL. Returns
 * ISO_EINVAL for NULL d or x; non-finite positions are sent as they are. */
ISO_API int iso_display_publish(iso_display *d, long tick, const double *x,
                                const iso_display_stats *stats, iso_err *err);

/* Foxglove, live. After this call the view's server also speaks Foxglove's
 * WebSocket protocol on /ws to a client that offers the subprotocol
 * "foxglove.websocket.v1" (Foxglove Studio's "Open connection"): it
 * advertises the session's channels, the same as an MCAP export's
 * (sinks/iso_foxglove.h), and streams the ticks iso_display_publish_frame
 * hands it, under the page's rules: latest wins, nothing waits for a
 * client, a client whose batch is unwritten ISO_DISPLAY_STALL_MS is
 * disconnected, and it counts among ISO_DISPLAY_MAX_VIEWERS. Its Origin,
 * when it sends one, must be the page's own or Foxglove's web app
 * (https://app.foxglove.dev). session->mesh must be the display's mesh.
 * Call it once, before the first publish. ISO_EINVAL, ISO_ENOMEM. */
struct iso_fox_session;
struct iso_fox_frame;
ISO_API ISO_NODISCARD int iso_display_foxglove(iso_display *d,
                                               const struct iso_fox_session *session, iso_err *err);

/* Hands the display the rest of a tick's channels (poses, devices, the
 * loop, actuators; f->x is ignored: the positions are those of the
 * iso_display_publish just before). A copy under the frame lock, no
 * allocation, no I/O. ISO_EINVAL for NULL arguments. */
ISO_API int iso_display_publish_frame(iso_display *d, const struct iso_fox_frame *f, iso_err *err);

/* Stops the server thread, closes every connection and frees everything.
 * Never waits on a browser: returns within one pass of the server's loop
 * even when a browser stopped reading. NULL is a no-op. */
ISO_API void iso_display_destroy(iso_display *d);

#endif
