/* view/display_listen.c -- the live view's listening socket: the address
 * it may bind (loopback unless allow_remote), how a Host header spells an
 * address, and the listen backlog policy of iso_display.h. */
#include "display_internal.h"
#include "iso_fd.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#define DEFER_ACCEPT_S 2    /* TCP_DEFER_ACCEPT: how long the kernel holds a silent connection */
#define LISTEN_BACKLOG 4096 /* the kernel caps it at net.core.somaxconn */

/* ---- addresses ------------------------------------------------------------ */

/* Spells a socket address as a Host header would: 1.2.3.4 or [::1]; a
 * v4-mapped IPv6 address as the IPv4 it is. */
void iso_display__host_spelling(const struct sockaddr *sa, char *out, size_t cap)
{
    char a[INET6_ADDRSTRLEN] = "?";
    if (sa->sa_family == AF_INET) {
        inet_ntop(AF_INET, &((const struct sockaddr_in *)sa)->sin_addr, a, sizeof a);
        snprintf(out, cap, "%s", a);
        return;
    }
    const struct in6_addr *v6 = &((const struct sockaddr_in6 *)sa)->sin6_addr;
    if (IN6_IS_ADDR_V4MAPPED(v6)) {
        inet_ntop(AF_INET, v6->s6_addr + 12, a, sizeof a);
        snprintf(out, cap, "%s", a);
        return;
    }
    inet_ntop(AF_INET6, v6, a, sizeof a);
    snprintf(out, cap, "[%s]", a);
}

static int is_loopback(const struct sockaddr *sa)
{
    if (sa->sa_family == AF_INET)
        return (ntohl(((const struct sockaddr_in *)sa)->sin_addr.s_addr) >> 24) == 127;
    const struct in6_addr *v6 = &((const struct sockaddr_in6 *)sa)->sin6_addr;
    if (IN6_IS_ADDR_V4MAPPED(v6))
        return v6->s6_addr[12] == 127;
    return IN6_IS_ADDR_LOOPBACK(v6);
}

static void notice(const iso_display_opts *o, const char *line)
{
    if (o->notice)
        o->notice(o->notice_ctx, line);
    else
        fprintf(stderr, "%s\n", line);
}

int iso_display__listen(iso_display *d, const iso_display_opts *o, iso_err *err)
{
    const char *host = o->host ? o->host : ISO_DISPLAY_DEFAULT_HOST;
    char h[128];
    size_t n = strlen(host);
    if (n >= sizeof h)
        return iso_err_set(err, ISO_EINVAL, -1, "display: host \"%.60s...\" is too long", host);
    if (n >= 2 && host[0] == '[' && host[n - 1] == ']') { /* [::1] as in a URL */
        memcpy(h, host + 1, n - 2);
        h[n - 2] = 0;
    } else {
        memcpy(h, host, n + 1);
    }
    if (strcasecmp(h, "localhost") == 0)
        snprintf(h, sizeof h, "127.0.0.1");
    char port[16];
    snprintf(port, sizeof port, "%d", o->port);
    struct addrinfo hints, *ai = NULL;
    memset(&hints, 0, sizeof hints);
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICHOST | AI_NUMERICSERV | AI_PASSIVE;
    if (getaddrinfo(h, port, &hints, &ai) != 0 || !ai)
        return iso_err_set(err, ISO_EINVAL, -1,
                           "display: host \"%s\" is not a numeric IPv4 or IPv6 address or "
                           "localhost",
                           host);
    char spelled[64];
    iso_display__host_spelling(ai->ai_addr, spelled, sizeof spelled);
    int rc = ISO_OK;
    if (!is_loopback(ai->ai_addr) && !o->allow_remote) {
        rc = iso_err_set(err, ISO_EINVAL, -1,
                         "display: refusing to listen on %s, which other machines can reach, "
                         "while the view has no password; set allow_remote (scene key "
                         "sinks.display.allow_remote: true) to do it anyway",
                         spelled);
        goto done;
    }
    int fd = socket(ai->ai_family, SOCK_STREAM, 0);
    if (fd < 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot open a socket for %s: %s", spelled,
                         strerror(errno));
        goto done;
    }
    int one = 1, defer = DEFER_ACCEPT_S;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    /* Connections that send nothing stay in the kernel: a flood of them
     * never takes a slot from a browser, whose request comes at once. */
    setsockopt(fd, IPPROTO_TCP, TCP_DEFER_ACCEPT, &defer, sizeof defer);
    if (bind(fd, ai->ai_addr, ai->ai_addrlen) != 0 || listen(fd, LISTEN_BACKLOG) != 0) {
        rc = iso_err_set(err, ISO_EIO, -1, "display: cannot serve on %s port %d: %s", spelled,
                         o->port, strerror(errno));
        close(fd);
        goto done;
    }
    (void)iso_fd_nonblock(fd);
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    getsockname(fd, (struct sockaddr *)&ss, &sl);
    d->port = ntohs(ss.ss_family == AF_INET ? ((struct sockaddr_in *)&ss)->sin_port
                                            : ((struct sockaddr_in6 *)&ss)->sin6_port);
    d->listen_fd = fd;
    snprintf(d->host_name, sizeof d->host_name, "%s", spelled);
    d->conns = calloc(ISO_DISPLAY_MAX_CONNS, sizeof *d->conns);
    if (!d->conns) {
        rc = iso_err_set(err, ISO_ENOMEM, -1, "display: out of memory");
        goto done;
    }
    for (int i = 0; i < ISO_DISPLAY_MAX_CONNS; i++)
        d->conns[i].fd = -1;
    d->remote = !is_loopback(ai->ai_addr);
    if (d->remote) {
        char line[256];
        snprintf(line, sizeof line,
                 "display: warning: the live view on %s port %d can be reached from other "
                 "machines, and anyone who reaches it sees the mesh (allow_remote is set)",
                 spelled, d->port);
        notice(o, line);
    }
done:
    freeaddrinfo(ai);
    return rc;
}
