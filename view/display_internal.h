/* view/display_internal.h -- private to view/: the page's text, the display's
 * state shared by its API (display.c), its server (display_server.c) and
 * the view protocol (display_viewer.c), and the WebSocket and HTTP pieces
 * (display_ws.c, display_http.c). */
#ifndef ISO_DISPLAY_INTERNAL_H
#define ISO_DISPLAY_INTERNAL_H

#include "iso_display.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

extern const char iso_display__page_html[];
extern const char iso_display__app_js[];

/* ---- WebSocket (display_ws.c) --------------------------------------------- */

/* Close statuses (RFC 6455 section 7.4.1). */
#define ISO_DISPLAY_WS_NORMAL 1000
#define ISO_DISPLAY_WS_GOING_AWAY 1001
#define ISO_DISPLAY_WS_PROTOCOL_ERROR 1002
#define ISO_DISPLAY_WS_NO_STATUS 1005 /* received without a status; never sent */
#define ISO_DISPLAY_WS_BAD_DATA 1007  /* e.g. text that is not UTF-8 */
#define ISO_DISPLAY_WS_TOO_BIG 1009

/* Writes the Sec-WebSocket-Accept value for a 24-character key into out.
 * Returns 0, or -1 when the key does not have 24 characters. */
int iso_display__ws_accept(const char *key, size_t key_len, char out[29]);

/* Writes an unmasked, final frame header for a payload of len bytes; returns
 * its length (2, 4 or 10). */
size_t iso_display__ws_header(unsigned char h[10], int opcode, size_t len);

/* Is this a close status an endpoint may send (1000-1003, 1007-1014,
 * 3000-4999)? */
int iso_display__ws_close_code_ok(int code);

/* UTF-8 checked a byte at a time across frames: no overlong forms, no
 * surrogates, nothing above U+10FFFF. */
typedef struct iso_display__utf8 {
    uint8_t need, lo, hi; /* continuation bytes still due, and the next one's range */
} iso_display__utf8;
/* 0 when b may come next, -1 when it may not. */
int iso_display__utf8_step(iso_display__utf8 *u, unsigned char b);

/* What a browser sends, parsed a byte at a time: frame headers judged as
 * they complete, payloads unmasked into a bounded message buffer (data) or
 * a control buffer, text checked as UTF-8 on the way. */
typedef struct iso_display__ws_rx {
    unsigned char hdr[14];
    unsigned hdr_len;
    uint64_t left; /* payload bytes of the current frame still to come */
    unsigned char mask[4];
    unsigned mask_at;
    int in_payload;  /* the header is done, the payload is being read */
    int opcode, fin; /* of the current frame */
    int msg_opcode;  /* 1 text or 2 binary while a message is open, else 0 */
    size_t msg_len;  /* its bytes so far */
    iso_display__utf8 utf8;
    unsigned char msg[ISO_DISPLAY_MAX_CLIENT_MESSAGE];
    unsigned char ctl[125];
    size_t ctl_len;
    long frames; /* frame headers seen */
} iso_display__ws_rx;

/* What a feed stopped at. */
enum {
    ISO_DISPLAY_WS_MORE = 0,    /* every byte consumed, nothing complete */
    ISO_DISPLAY_WS_MESSAGE = 1, /* a whole message: opcode, data, len */
    ISO_DISPLAY_WS_PING = 2,    /* data, len: the payload to answer with */
    ISO_DISPLAY_WS_PONG = 3,
    ISO_DISPLAY_WS_CLOSE = 4, /* the peer closes: code (1005 when it gave none) */
    ISO_DISPLAY_WS_FAIL = 5   /* a violation: code is the status to close with */
};
typedef struct iso_display__ws_event {
    int opcode; /* MESSAGE: 1 text, 2 binary */
    const unsigned char *data;
    size_t len;
    int code;
} iso_display__ws_event;

/* Feeds up to n bytes and stops after the first event; *used says how many
 * were consumed. Returns ISO_DISPLAY_WS_* (MORE when all n were used and
 * nothing completed). After CLOSE or FAIL the parser must not be fed again.
 * An event's data points into rx and holds until the next feed. */
int iso_display__ws_rx_feed(iso_display__ws_rx *rx, const unsigned char *p, size_t n, size_t *used,
                            iso_display__ws_event *ev);

/* ---- HTTP (display_http.c) ------------------------------------------------ */

/* The parts of a request the view reads; pointers into the caller's buffer. */
typedef struct iso_display__request {
    const char *method, *path, *query; /* path without its query; query without '?' */
    size_t method_len, path_len, query_len;
    const char *host, *origin, *upgrade, *key, *version, *protocol; /* NULL when absent */
    size_t host_len, origin_len, upgrade_len, key_len, version_len, protocol_len;
} iso_display__request;

/* Splits a request: buf is NUL-terminated and holds the request line and
 * the headers up to and including the empty line. Returns 0, or -1 when the
 * request line is malformed or a line does not end in CRLF (a NUL byte
 * inside the request ends it early: the server refuses those before). */
int iso_display__parse_request(char *buf, iso_display__request *r);

/* Is `a` (n bytes: HOST or HOST:PORT, as in a Host header or after an
 * origin's scheme) one of names[] (NULL entries skipped)? A port, when
 * given, must be `port`; without one it must be too (80) unless
 * port_optional (a Host header may leave it out). */
int iso_display__authority_is(const char *a, size_t n, int port, int port_optional,
                              const char *const *names, size_t n_names);

/* The value of `key` in a query (k=v&k2=v2, no decoding: tokens are hex);
 * NULL when absent. *len gets its length. */
const char *iso_display__query_get(const char *q, size_t n, const char *key, size_t *len);

/* Case-insensitive: [p, p+n) equals s / contains s. */
int iso_display__token_eq(const char *p, size_t n, const char *s);
int iso_display__contains_ci(const char *p, size_t n, const char *s);
/* Is s one of the comma-separated tokens in [p, p + n), to the letter
 * (white space around each ignored)? Subprotocol names are matched so: an
 * offer that merely contains a name is not that name. */
int iso_display__list_has(const char *p, size_t n, const char *s);

/* ---- Foxglove's protocol (foxglove_live.c, foxglove_live_rx.c) ----------------------- */

/* What a Foxglove client says, and the subscriptions it asked for. */
#define ISO_DISPLAY_FOX_MAX_CHANNELS 64
typedef struct iso_display__fox_rx {
    long sub[ISO_DISPLAY_FOX_MAX_CHANNELS]; /* subscription id per channel, -1: none */
    char msg[ISO_DISPLAY_MAX_CLIENT_MESSAGE + 1];
    long messages; /* text messages taken */
    /* What the client is told back (a "status" message, level warning):
     * an op that is not served, a channel that is not advertised. The
     * newest replaces one not yet sent; status_ver counts them. */
    char status[160];
    long status_ver;
} iso_display__fox_rx;

void iso_display__fox_rx_init(iso_display__fox_rx *rx);
/* One whole text message (n bytes, any content) from a client of a session
 * with n_channels channels: subscribes and unsubscribes as told; an op it
 * does not serve, or a subscription to a channel it does not have, sets
 * the status the client is told. A message longer than ISO_DISPLAY_MAX_CLIENT_MESSAGE is cut
 * there (the WebSocket reader refuses those before). */
void iso_display__fox_rx_message(iso_display__fox_rx *rx, int n_channels, const unsigned char *p,
                                 size_t n);

typedef struct iso_display__fox iso_display__fox;               /* one client's */
typedef struct iso_display__fox_shared iso_display__fox_shared; /* all clients' */

/* Does the request (NUL-terminated, headers included) offer Foxglove's
 * subprotocol? */
int iso_display__fox_offered(const char *req);
/* Wakes the server thread unless a wake is on its way; never blocks, any
 * thread (display.c). */
void iso_display__wake(iso_display *d);
void iso_display__fox_shared_free(iso_display__fox_shared *s);

/* ---- connections ----------------------------------------------------------- */

typedef struct iso_display__conn iso_display__conn;

/* A kind of WebSocket connection: what it sends, what it takes. The view's
 * own protocol (display_viewer.c) is the default; another (chosen by
 * Sec-WebSocket-Protocol) adds a table like it and its fields to the
 * connection. Each function runs on the server's thread. */
typedef struct iso_display__proto {
    const char *name; /* the Sec-WebSocket-Protocol it answers to; NULL: the default */
    /* The upgrade was accepted (its 101 answer is queued): start the kind's
     * state. Returns 0, or an HTTP status to answer with instead (503). */
    int (*open)(iso_display *d, iso_display__conn *c, const iso_display__request *r);
    /* A whole message from the browser. Returns 0, or a close status. */
    int (*message)(iso_display *d, iso_display__conn *c, int opcode, const unsigned char *p,
                   size_t n);
    /* The last message is written whole: queue the next one (set_output).
     * Returns 1 when one was queued. */
    int (*next)(iso_display *d, iso_display__conn *c, long long now);
    /* The connection ends, whatever the reason. */
    void (*close)(iso_display *d, iso_display__conn *c);
} iso_display__proto;

extern const iso_display__proto iso_display__view_proto;
extern const iso_display__proto iso_display__fox_proto; /* foxglove_live.c */

typedef enum iso_display__conn_state {
    C_FREE,
    C_REQUEST,  /* reading the request line and headers */
    C_RESPONSE, /* writing a response, then C_LINGER */
    C_LINGER,   /* written and shut down for writing; draining until the peer closes */
    C_SOCKET    /* a WebSocket */
} iso_display__conn_state;

typedef enum iso_display__viewer_stage { V_HANDSHAKE, V_TOPOLOGY, V_FRAMES } iso_display__stage;

/* The view protocol's part of a connection. */
typedef struct iso_display__viewer {
    iso_display__stage stage;
    unsigned char *frame; /* its own copy of the frame being written */
    unsigned long frame_seq;
    int writing_frame;
    int paced;                   /* it has said "took" once: a frame at a time from then on */
    double sent_tick, took_tick; /* of the last frame queued to it, of its last "took" */
    int may_command;             /* passed the checks, and the token when one is needed */
    unsigned control_ver;        /* the control state last sent to it */
    unsigned note_ver;           /* the note last sent to it */
    char why[96];                /* why its last command was refused */
    char text[512];              /* the control message being written */
} iso_display__viewer;

struct iso_display__conn {
    int fd;
    iso_display__conn_state state;
    long long since;      /* ms: accepted, or the current message queued */
    unsigned long serial; /* order of acceptance: the oldest request yields its slot */
    uint32_t id;          /* a WebSocket's number, as the device's envelopes name it */
    long long deadline;   /* ms: when this connection is given up */
    int patient;          /* the current message may take longer than the stall bound
                             while it makes progress (the topology) */
    char local[64];       /* the address it arrived on, as a Host header spells it */

    char req[ISO_DISPLAY_MAX_REQUEST + 1];
    size_t req_len;

    /* Output: head, then body; out_pos counts over both. */
    char head[1024];
    size_t head_len;
    const unsigned char *body;
    size_t body_len, out_pos;
    /* A control frame to send between messages (a pong); 0 = none. */
    unsigned char ctl_out[2 + 125];
    size_t ctl_len;

    /* WebSocket */
    const iso_display__proto *proto;
    iso_display__ws_rx rx;
    iso_display__viewer v;
    iso_display__fox *fox; /* Foxglove's part (foxglove_live.c) */
};

/* ---- the display's state -------------------------------------------------- */

struct iso_display {
    /* Fixed at create. */
    const iso_mesh *mesh;
    int nv, nh, port;
    int listen_fd;
    int remote;                         /* bound beyond loopback */
    char host_name[64];                 /* the bound address as a Host header spells it: [::1] */
    char *three, *orbit, *gizmo, *gltf; /* file contents; all but three may be NULL */
    size_t three_len, orbit_len, gizmo_len, gltf_len;
    char *topology; /* the binary message sent on connect */
    size_t topology_len;
    size_t frame_len;
    int wake[2];         /* pipe: publish and destroy wake the server */
    iso_dev_source *dev; /* the view device, or NULL: read-only */
    int n_cmd_handles;
    char token[33]; /* "" when none is needed */

    /* The latest frame: publish writes it under frame_lock; the server copies
     * it out under the same lock. Nobody holds the lock for anything else. */
    pthread_mutex_t frame_lock;
    unsigned char *latest;
    unsigned long latest_seq;         /* under frame_lock; 0 = nothing yet */
    atomic_ulong published;           /* latest_seq, readable without the lock */
    struct iso_sink_frame *fox_frame; /* under frame_lock: the last publish_frame's copy */
    unsigned long fox_frame_seq;
    _Atomic(iso_display__fox_shared *) fox; /* set once by iso_display_foxglove */
    atomic_int wake_pending;                /* a byte is in the pipe: publish need not write */
    atomic_int stopping;

    /* The run's end (iso_display_end): note_lock guards note. */
    pthread_mutex_t note_lock;
    char *note;
    atomic_uint note_ver;
    atomic_int ended;

    /* Read by the status line without any lock; written by the server. */
    atomic_int viewers;
    atomic_long frames_sent;
    atomic_uint holder;
    atomic_uint cmd_accepted, cmd_refused, cmd_malformed, cmd_dropped, cmd_grants, cmd_stops;

    /* The server thread's own; no one else touches these. */
    pthread_t server;
    int server_started;
    iso_display__conn *conns;      /* ISO_DISPLAY_MAX_CONNS */
    unsigned long counted_seq;     /* newest frame counted in frames_sent */
    unsigned long accepted;        /* connections accepted so far */
    uint32_t next_id;              /* WebSockets numbered so far */
    long long accept_paused_until; /* ms: out of descriptors, accept later */
    unsigned control_ver;          /* bumped when the holder or the stop changes */
    int stop;                      /* a page's stop pressed, as the server saw it */
    uint32_t stop_conn;            /* who pressed it */
    long long stop_ms;             /* when (iso_display__now_ms) */
    long long holder_ms;           /* when the holder's last command came */
};

long long iso_display__now_ms(void);

/* Spells a socket address as a Host header would: 1.2.3.4 or [::1]; a
 * v4-mapped IPv6 address as the IPv4 it is (display_listen.c). */
struct sockaddr;
void iso_display__host_spelling(const struct sockaddr *sa, char *out, size_t cap);

/* Opens the listening socket for opts (display_listen.c). */
int iso_display__listen(iso_display *d, const iso_display_opts *opts, iso_err *err);

/* The server thread's body (display_server.c). */
void *iso_display__serve(void *arg);

/* Frees what the server thread left (connections, the listener). */
void iso_display__server_free(iso_display *d);

/* Output of a connection (display_server.c): what to write next. */
void iso_display__set_output(iso_display__conn *c, const void *body, size_t len);
/* Queues a WebSocket message: header into c->head, body as given. */
void iso_display__queue_message(iso_display__conn *c, int opcode, const void *body, size_t len);

/* The view protocol's hooks for the server (display_viewer.c): the end of
 * the run reaches each viewer; the stop state changed. */
void iso_display__viewer_end(iso_display *d);
/* Ends the control of a holder silent for ISO_DISPLAY_LAPSE_MS (each
 * server turn). */
void iso_display__viewer_lapse(iso_display *d, long long now);

#endif
