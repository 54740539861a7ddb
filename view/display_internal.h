/* view/display_internal.h -- private to view/: the page's text, the display's
 * state shared by its API (display.c) and its server (display_server.c),
 * and the WebSocket pieces (display_ws.c). */
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

/* Close statuses (RFC 6455 section 7.4.1) the parser returns. */
#define ISO_DISPLAY_WS_NORMAL 1000
#define ISO_DISPLAY_WS_PROTOCOL_ERROR 1002
#define ISO_DISPLAY_WS_TOO_BIG 1009

/* Writes the Sec-WebSocket-Accept value for a 24-character key into out.
 * Returns 0, or -1 when the key does not have 24 characters. */
int iso_display__ws_accept(const char *key, size_t key_len, char out[29]);

/* Writes an unmasked, final frame header for a payload of len bytes; returns
 * its length (2, 4 or 10). */
size_t iso_display__ws_header(unsigned char h[10], int opcode, size_t len);

/* What a browser sends, parsed a byte at a time and thrown away. */
typedef struct iso_display__ws_rx {
    unsigned char hdr[14];
    unsigned hdr_len;
    uint64_t skip; /* payload bytes of the current frame still to discard */
    long frames;   /* frame headers seen */
} iso_display__ws_rx;

/* Feeds n bytes. Returns 0 to go on, or the status to close with:
 * ISO_DISPLAY_WS_NORMAL (the browser sent a close frame),
 * ISO_DISPLAY_WS_PROTOCOL_ERROR (unmasked frame, reserved bits, a long or
 * fragmented control frame) or ISO_DISPLAY_WS_TOO_BIG (a payload announced
 * above ISO_DISPLAY_MAX_CLIENT_FRAME). */
int iso_display__ws_rx_feed(iso_display__ws_rx *rx, const unsigned char *p, size_t n);

/* ---- HTTP (display_http.c) ------------------------------------------------ */

/* The parts of a request the view reads; pointers into the caller's buffer. */
typedef struct iso_display__request {
    const char *method, *path; /* path without its query */
    size_t method_len, path_len;
    const char *host, *origin, *upgrade, *key, *version; /* NULL when absent */
    size_t host_len, origin_len, upgrade_len, key_len, version_len;
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

/* Case-insensitive: [p, p+n) equals s / contains s. */
int iso_display__token_eq(const char *p, size_t n, const char *s);
int iso_display__contains_ci(const char *p, size_t n, const char *s);

/* ---- Foxglove's protocol (foxglove.c, foxglove_rx.c) ----------------------- */

/* What a Foxglove client sends, parsed into a fixed buffer, and the
 * subscriptions it asked for. */
#define ISO_DISPLAY_FOX_MAX_CHANNELS 64
typedef struct iso_display__fox_rx {
    long sub[ISO_DISPLAY_FOX_MAX_CHANNELS]; /* subscription id per channel, -1: none */
    unsigned char hdr[14];
    unsigned hdr_len;
    int in_payload;
    uint64_t need, got;
    int opcode;
    unsigned char mask[4];
    unsigned char msg[ISO_DISPLAY_MAX_CLIENT_FRAME + 1];
    long messages; /* text messages taken */
} iso_display__fox_rx;

void iso_display__fox_rx_init(iso_display__fox_rx *rx);
/* Feeds n bytes from a client of a session with n_channels channels.
 * Returns 0 to go on, or the status to close with (as
 * iso_display__ws_rx_feed). Subscribes and unsubscribes as told. */
int iso_display__fox_rx_feed(iso_display__fox_rx *rx, int n_channels, const unsigned char *p,
                             size_t n);

typedef struct iso_display__fox iso_display__fox;               /* one client's */
typedef struct iso_display__fox_shared iso_display__fox_shared; /* all clients' */

/* Does the request (NUL-terminated, headers included) offer Foxglove's
 * subprotocol? */
int iso_display__fox_offered(const char *req);
const char *iso_display__fox_subprotocol(void);
iso_display__fox *iso_display__fox_create(void); /* NULL: out of memory */
void iso_display__fox_free(iso_display__fox *f);
void iso_display__fox_shared_free(iso_display__fox_shared *s);
/* The client's next message: 1 with *body and *len set (valid until the
 * next call), 0 when it has nothing to send now, -1 out of memory. */
int iso_display__fox_next(iso_display *d, iso_display__fox *f, const unsigned char **body,
                          size_t *len);
/* Feeds what the client sent; 0 to go on, else the status to close with. */
int iso_display__fox_read(iso_display *d, iso_display__fox *f, const unsigned char *p, size_t n);

/* ---- the display's state -------------------------------------------------- */

typedef struct iso_display__conn iso_display__conn; /* display_server.c */

struct iso_display {
    /* Fixed at create. */
    const iso_mesh *mesh;
    int nv, port;
    int listen_fd;
    char host_name[64];         /* the bound address as a Host header spells it: [::1] */
    char *three, *orbit, *gltf; /* file contents; orbit and gltf may be NULL */
    size_t three_len, orbit_len, gltf_len;
    char *topology; /* the JSON sent on connect */
    size_t topology_len;
    size_t frame_len;
    int wake[2]; /* pipe: publish and destroy wake the server */

    /* The latest frame: publish writes it under frame_lock; the server copies
     * it out under the same lock. Nobody holds the lock for anything else. */
    pthread_mutex_t frame_lock;
    unsigned char *latest;
    unsigned long latest_seq;        /* under frame_lock; 0 = nothing yet */
    atomic_ulong published;          /* latest_seq, readable without the lock */
    struct iso_fox_frame *fox_frame; /* under frame_lock: the last publish_frame's copy */
    unsigned long fox_frame_seq;
    _Atomic(iso_display__fox_shared *) fox; /* set once by iso_display_foxglove */
    atomic_int wake_pending;                /* a byte is in the pipe: publish need not write */
    atomic_int stopping;

    /* Read by the status line without any lock; written by the server. */
    atomic_int viewers;
    atomic_long frames_sent;

    /* The server thread's own; no one else touches these. */
    pthread_t server;
    int server_started;
    iso_display__conn *conns;      /* ISO_DISPLAY_MAX_CONNS */
    unsigned long counted_seq;     /* newest frame counted in frames_sent */
    unsigned long accepted;        /* connections accepted so far */
    long long accept_paused_until; /* ms: out of descriptors, accept later */
};

/* Opens the listening socket for opts (display_server.c). */
int iso_display__listen(iso_display *d, const iso_display_opts *opts, iso_err *err);

/* The server thread's body (display_server.c). */
void *iso_display__serve(void *arg);

/* Frees what the server thread left (connections, the listener). */
void iso_display__server_free(iso_display *d);

#endif
