/* tests/vm/mcu_tty.c -- the actuator MCU's protocol logic (iso_fb_mcu.c,
 * with the firmware's channel configuration) on a serial device: in the VM
 * it serves the gadget side of a USB CDC-ACM link (/dev/ttyGS0) while
 * `isoshape run` drives its actuators over the host side (/dev/ttyACM0,
 * libserialport), as it would a USB-connected microcontroller.
 *
 *   vm_mcu TTY LOG
 *
 * Runs until SIGTERM or SIGINT; logs every state change (IDLE, ARMED,
 * SAFE) with its CLOCK_MONOTONIC time in ms, and at the end the counters
 * and positions. A write the host side does not take (nobody has the tty
 * open) is dropped, as a UART's would be. When the USB link goes (the
 * gadget unplugged: the tty hangs up) the logic runs on, as a powered MCU
 * does, and the tty is opened again every 50 ms. */
#define _DEFAULT_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "iso_actuators.h"
#include "iso_fb_mcu.h"

static struct {
    int fd;
    FILE *log;
    long tx_dropped, rx_bytes;
    volatile sig_atomic_t stop;
} g;

static uint32_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint32_t)((uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u);
}

static void mcu_write(void *ctx, const uint8_t *b, size_t n)
{
    (void)ctx;
    while (n > 0 && g.fd >= 0) {
        ssize_t k = write(g.fd, b, n);
        if (k <= 0) {
            g.tx_dropped += (long)n;
            return;
        }
        b += k;
        n -= (size_t)k;
    }
}

static void on_signal(int sig)
{
    (void)sig;
    g.stop = 1;
}

static const char *state_name(int s)
{
    return s == ISO_FB_STATE_ARMED ? "ARMED" : s == ISO_FB_STATE_SAFE ? "SAFE" : "IDLE";
}

static int open_tty(const char *path)
{
    int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    struct termios t;
    if (fd >= 0 && tcgetattr(fd, &t) == 0) {
        cfmakeraw(&t);
        cfsetspeed(&t, B115200);
        tcsetattr(fd, TCSANOW, &t);
    }
    return fd;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: vm_mcu TTY LOG\n");
        return 2;
    }
    g.fd = open_tty(argv[1]);
    g.log = fopen(argv[2], "w");
    if (g.fd < 0 || !g.log) {
        fprintf(stderr, "vm_mcu: cannot open %s or %s: %s\n", argv[1], argv[2], strerror(errno));
        return 1;
    }
    setvbuf(g.log, NULL, _IOLBF, 0);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_board(&cfg);
    static iso_fb_mcu m;
    if (iso_fb_mcu_init(&m, &cfg, mcu_write, NULL, now_ms()) != 0) {
        fprintf(stderr, "vm_mcu: the firmware configuration is invalid\n");
        return 1;
    }
    fprintf(g.log, "%u state %s\n", now_ms(), state_name(m.state));
    int last = m.state;
    uint32_t retry = 0;
    while (!g.stop) {
        if (g.fd < 0 && now_ms() - retry >= 50) {
            retry = now_ms();
            if ((g.fd = open_tty(argv[1])) >= 0)
                fprintf(g.log, "%u link up\n", now_ms());
        }
        struct pollfd p = {g.fd, POLLIN, 0};
        if (g.fd < 0) {
            usleep(1000);
        } else if (poll(&p, 1, 1) > 0) {
            uint8_t buf[256];
            ssize_t n = read(g.fd, buf, sizeof buf);
            if (n > 0) {
                g.rx_bytes += n;
                iso_fb_mcu_rx(&m, buf, (size_t)n);
            } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
                fprintf(g.log, "%u link down (%s)\n", now_ms(),
                        n == 0 ? "hung up" : strerror(errno));
                close(g.fd);
                g.fd = -1;
                retry = now_ms();
            }
        }
        iso_fb_mcu_tick(&m, now_ms());
        if (m.state != last) {
            fprintf(g.log, "%u state %s\n", now_ms(), state_name(m.state));
            last = m.state;
        }
    }
    fprintf(g.log,
            "end: %u setpoints applied, %u clamped, %u naks, %u faults, %ld bytes in, %ld "
            "out dropped, state %s, positions",
            m.setpoints_applied, m.clamped, m.naks, m.faults, g.rx_bytes, g.tx_dropped,
            state_name(m.state));
    for (unsigned c = 0; c < cfg.n_channels; c++)
        fprintf(g.log, " %d", iso_fb_mcu_position(&m, c));
    fprintf(g.log, "\n");
    fclose(g.log);
    if (g.fd >= 0)
        close(g.fd);
    return 0;
}
