/* tests/cdp.h -- a small Chrome DevTools Protocol client for the tests of
 * the live view: it starts Debian's headless Chromium with
 * --remote-debugging-pipe (commands on the child's fd 3, answers and events
 * on its fd 4, each message JSON ending in a NUL byte), opens one page, and
 * drives it: evaluate script, wait for page state, move and press the mouse,
 * press keys, take screenshots.
 *
 * Tests wait on the page's own state (iso_cdp_wait polls an expression)
 * rather than on virtual time: --virtual-time-budget advances only while
 * the page is idle, and a page that draws every frame of a live stream is
 * rarely idle, so under load 4 s of virtual time took 38 s of wall time
 * and the check timed out. Every wait here has a wall-clock bound and
 * returns as soon as its condition holds. */
#ifndef ISO_TEST_CDP_H
#define ISO_TEST_CDP_H

#include <stddef.h>
#include <sys/types.h>

#define ISO_CDP_CHROMIUM "/usr/bin/chromium"

typedef struct iso_cdp {
    pid_t pid;
    int to_fd, from_fd; /* our ends of the child's fd 3 and fd 4 */
    char *buf;          /* bytes read, not yet split into messages */
    size_t len, cap;
    int next_id;
    char session[128]; /* the page's session (Target.attachToTarget, flatten) */
    char profile[512];
    char why[512]; /* the last failure, as a sentence */
} iso_cdp;

/* Starts Chromium (window 800x600, SwiftShader WebGL) with a fresh profile
 * in `profile` and its stderr in `log`. Returns 0; -1 with c->why; 77 when
 * Chromium is not installed. */
int iso_cdp_start(iso_cdp *c, const char *profile, const char *log);
/* Opens url in a new page and attaches to it. Returns 0 or -1 (c->why). */
int iso_cdp_open(iso_cdp *c, const char *url, int timeout_ms);
/* Sends a command (to the page when on_page) and waits for its answer.
 * Returns the answer's JSON (malloc'd; the caller frees it), or NULL with
 * c->why (a timeout, an error answer, Chromium gone). */
char *iso_cdp_call(iso_cdp *c, int on_page, const char *method, const char *params, int timeout_ms);
/* Evaluates expr in the page; its value must be a string (use
 * JSON.stringify). Returns the string, unescaped and malloc'd, or NULL. */
char *iso_cdp_eval(iso_cdp *c, const char *expr, int timeout_ms);
/* Polls the JavaScript boolean expression cond every 50 ms until it holds
 * (returns 1) or timeout_ms passes (returns 0). */
int iso_cdp_wait(iso_cdp *c, const char *cond, int timeout_ms);
/* A mouse event at viewport point (x, y): type "mouseMoved", "mousePressed"
 * or "mouseReleased", of the left button (event.button 0, as a plain move
 * has too); left: it is held down (buttons 1). */
int iso_cdp_mouse(iso_cdp *c, const char *type, double x, double y, int left);
/* A key pressed and released: key as KeyboardEvent.key ("Escape", "x"),
 * code as KeyboardEvent.code, its Windows key code. */
int iso_cdp_key(iso_cdp *c, const char *key, const char *code, int keycode, int shift);
/* Writes a PNG of the page to path. Returns 0 or -1. */
int iso_cdp_screenshot(iso_cdp *c, const char *path);
/* Ends Chromium and removes the profile. */
void iso_cdp_stop(iso_cdp *c);

/* A number from a flat JSON text: the value after "key": (NAN if absent). */
double iso_cdp_num(const char *json, const char *key);

#endif
