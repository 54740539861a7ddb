/* tests/ws_client.h -- a minimal HTTP and WebSocket client for the tests of
 * the live view (test_display, test_run_view): loopback connections, a
 * request's head, the /ws upgrade, and a reader thread that counts frames. */
#ifndef ISO_TEST_WS_CLIENT_H
#define ISO_TEST_WS_CLIENT_H

#include <pthread.h>
#include <stdatomic.h>

/* Connects to the loopback of `family` (AF_INET or AF_INET6) with a 5 s
 * receive timeout and, when rcvbuf > 0, that receive buffer; -1 if not. */
int iso_test_connect(int family, int port, int rcvbuf);
/* Writes all of s; asserts. */
void iso_test_send_all(int fd, const char *s);
/* Reads a response's status line and headers (to the empty line) into buf;
 * returns the status code, -1 when there is none. */
int iso_test_read_head(int fd, char *buf, size_t cap);
/* Opens /ws with `extra` headers (each ending in \r\n); returns the fd and
 * stores the answer's status. */
int iso_test_ws_open(int family, int port, const char *host, const char *extra, int rcvbuf,
                     int *status);

/* Sends one masked client frame: fin, opcode, payload (any length). */
void iso_test_ws_send(int fd, int fin, int opcode, const void *payload, size_t len);
/* Reads one server frame (unmasked); returns its opcode (and fin in *fin
 * when not NULL) and a malloc'd payload, or -1 when the connection ended
 * or timed out first. */
int iso_test_ws_recv(int fd, unsigned char **payload, size_t *len);
/* Reads frames until a close frame and returns its status (1005 when it
 * has none), -1 when the connection ended without one. Pongs and other
 * frames on the way are skipped; *pongs counts the pongs (may be NULL). */
int iso_test_ws_close_status(int fd, int *pongs);
/* Opens /ws and reads the topology and the first control message; returns
 * the fd, or -1. */
int iso_test_ws_viewer(int port, const char *extra);
/* The JSON of a binary topology message (iso_display.h), malloc'd, or NULL
 * when the message is no whole topology. */
char *iso_test_topology_json(const unsigned char *msg, size_t len);
/* The bounding-box diagonal of a topology message's rest positions, NAN
 * when the message is no whole topology. */
double iso_test_topology_diagonal(const unsigned char *msg, size_t len);

/* Reads frames on its own thread until the socket ends. Binary frames carry
 * the tick (a double at byte 8), the topology aside (its own magic); a
 * tick that does not grow sets failed. No
 * cmocka asserts run off the main thread. frames and bytes may be read while
 * it runs (a measuring tool's rates); the rest once it is stopped. */
typedef struct iso_test_ws_reader {
    int fd;
    atomic_long frames;         /* binary frames received, the topology aside */
    atomic_long bytes;          /* their payload bytes */
    atomic_long text_bytes;     /* the payload bytes of text frames (the control state...) */
    atomic_long topology_bytes; /* the payload bytes of the topology */
    double last_tick;           /* the newest tick in them */
    int failed;
    pthread_t th;
} iso_test_ws_reader;
void iso_test_ws_reader_start(iso_test_ws_reader *r, int fd);
/* Shuts the socket down, joins the thread and closes the fd. */
void iso_test_ws_reader_stop(iso_test_ws_reader *r);

#endif
