/* tests/tools/view_tcp_memory.c -- what viewers that never read cost the
 * kernel: a live view of a 100 KB frame (the cylinder at resolution 64),
 * published at 50 Hz, while a viewer that opens its WebSocket and never
 * reads another byte arrives every 100 ms; every 5 s it prints this
 * machine's TCP line of /proc/net/sockstat (sockets in use, orphans, and
 * "mem", the kernel's TCP memory in pages). The server drops each such
 * viewer after ISO_DISPLAY_STALL_MS; what matters is whether what it had
 * not sent stays in the kernel (orphans, growing mem) or leaves with the
 * drop (a reset).
 *   usage: view_tcp_memory [SECONDS]   (default 30) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "iso_display.h"
#include "iso_mesh.h"
#include "iso_regions.h"
#include "iso_shapes.h"
#include "ws_client.h"

static void sockstat(const char *when)
{
    FILE *f = fopen("/proc/net/sockstat", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, "TCP:", 4) == 0)
            printf("%-22s %s", when, line);
    if (f)
        fclose(f);
    fflush(stdout);
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

int main(int argc, char **argv)
{
    int secs = argc > 1 ? atoi(argv[1]) : 30;
    iso_shape sh;
    iso_mesh *m = NULL;
    iso_regions r;
    iso_err e;
    iso_err_clear(&e);
    if (iso_shape_init(&sh, "cylinder", 64, &e) != ISO_OK ||
        iso_mesh_create(sh.nv, sh.x, sh.nt, sh.tri, "cylinder", &m, &e) != ISO_OK ||
        iso_shape_regions(&sh, &r, &e) != ISO_OK) {
        fprintf(stderr, "view_tcp_memory: %s\n", e.msg);
        return 1;
    }
    iso_display_opts o;
    memset(&o, 0, sizeof o);
    o.mesh = m;
    o.regions = &r;
    iso_display *d = NULL;
    if (iso_display_create(&o, &d, &e) != ISO_OK) {
        fprintf(stderr, "view_tcp_memory: %s\n", e.msg);
        return 1;
    }
    int port = iso_display_port(d);
    char host[64];
    snprintf(host, sizeof host, "127.0.0.1:%d", port);
    sockstat("start");
    static int fds[4096];
    int n = 0;
    double t0 = now_s(), last = -5;
    for (long tick = 0; now_s() - t0 < secs; tick++) {
        iso_display_publish(d, tick, sh.x, NULL, NULL);
        if (tick % 5 == 0 && n < 4000) { /* a viewer with a 4 KiB buffer that never reads */
            int st;
            fds[n++] = iso_test_ws_open(AF_INET, port, host, "", 4096, &st);
        }
        if (now_s() - t0 >= last + 5) {
            last = now_s() - t0;
            char when[64];
            snprintf(when, sizeof when, "t=%2.0f s, %d viewers:", last, iso_display_clients(d));
            sockstat(when);
        }
        struct timespec ts = {0, 20 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    sockstat("end");
    iso_display_destroy(d);
    for (int i = 0; i < n; i++)
        close(fds[i]);
    iso_regions_deinit(&r);
    iso_mesh_destroy(m);
    iso_shape_deinit(&sh);
    return 0;
}
