/* tests/tools/child_stderr.h -- what a measuring tool keeps of the
 * `isoshape run` it started: the child's stderr, read on a thread of its
 * own into a buffer (so the child never blocks on it), and the live view's
 * port found in it. Header-only; the tools that include it are one
 * program each. */
#ifndef ISO_TOOLS_CHILD_STDERR_H
#define ISO_TOOLS_CHILD_STDERR_H

#include <fcntl.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

typedef struct child_stderr {
    int fd; /* the read end of the child's stderr */
    pthread_mutex_t mu;
    char text[1 << 20];
    size_t len;
    pthread_t th;
} child_stderr;

static void *child_stderr_main(void *arg)
{
    child_stderr *c = arg;
    char buf[4096];
    ssize_t n;
    while ((n = read(c->fd, buf, sizeof buf)) > 0) {
        pthread_mutex_lock(&c->mu);
        size_t room = sizeof c->text - 1 - c->len, k = (size_t)n < room ? (size_t)n : room;
        memcpy(c->text + c->len, buf, k);
        c->len += k;
        c->text[c->len] = 0;
        pthread_mutex_unlock(&c->mu);
    }
    return NULL;
}

/* Starts reading fd (the read end of the child's stderr pipe). */
static inline void child_stderr_start(child_stderr *c, int fd)
{
    c->fd = fd;
    c->len = 0;
    c->text[0] = 0;
    pthread_mutex_init(&c->mu, NULL);
    pthread_create(&c->th, NULL, child_stderr_main, c);
}

/* Starts argv[0] with argv, its stdin and stdout /dev/null and its stderr
 * read into c; the child's pid, or -1. */
static inline pid_t child_stderr_run(char *const argv[], child_stderr *c)
{
    int err[2];
    if (pipe(err) != 0)
        return -1;
    pid_t pid = fork();
    if (pid == 0) {
        dup2(err[1], 2);
        int nul = open("/dev/null", O_RDWR);
        dup2(nul, 0);
        dup2(nul, 1);
        execv(argv[0], argv);
        _exit(127);
    }
    close(err[1]);
    if (pid < 0) {
        close(err[0]);
        return -1;
    }
    child_stderr_start(c, err[0]);
    return pid;
}

/* Waits for the child's end of the pipe to close (the child exited). */
static inline void child_stderr_join(child_stderr *c)
{
    pthread_join(c->th, NULL);
}

/* The live view's port, once the child has said it; -1 before. */
static inline int child_stderr_port(child_stderr *c)
{
    const char *key = "live view on http://127.0.0.1:";
    pthread_mutex_lock(&c->mu);
    const char *at = strstr(c->text, key);
    int port = at && strchr(at, '\n') ? atoi(at + strlen(key)) : -1;
    pthread_mutex_unlock(&c->mu);
    return port;
}

#endif
