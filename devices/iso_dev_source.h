/* devices/iso_dev_source.h -- sources: the one interface every backend
 * fills (iso_dev_source_ops), the calls that go through it, and each
 * backend's open function (simulated, OS and hardware backends, one file
 * each in devices/). A source only hands out chunks (iso_dev.h); what they
 * say is decoded apart from it (iso_dev_decode.h), so that a backend is
 * its I/O alone and a replay can stand in for any of them. Finding what is
 * connected is iso_dev_enum.h; the view's source comes with its command
 * format (iso_dev_view.h), the replay source with the recordings
 * (iso_dev_rec.h). */
#ifndef ISO_DEV_SOURCE_H
#define ISO_DEV_SOURCE_H

#include <stddef.h>
#include <stdint.h>

#include "iso_dev.h"
#include "iso_err.h"

/* ====================================================================== */
/* Sources: one interface, one backend per file                            */
/* ====================================================================== */

typedef struct iso_dev_source iso_dev_source;
typedef struct iso_dev_source_ops {
    const char *backend; /* "hidapi", "tty", "tcp", ... */
    /* A descriptor to poll for input, or -1 (hidapi has none: read each tick). */
    int (*fd)(iso_dev_source *s);
    /* Reads what is there without blocking: returns 1 and fills *out (data
     * stamped at or before until_ns), 0 when there is nothing now, or a
     * negative ISO_E* code with err filled when the device is gone. */
    int (*read)(iso_dev_source *s, int64_t until_ns, iso_dev_chunk *out, iso_err *err);
    /* Optional: drives an output line (GPIO trigger); NULL if none. */
    int (*write_level)(iso_dev_source *s, int level, iso_err *err);
    void (*close)(iso_dev_source *s);
    /* Optional: the e-stop input's level now, read without blocking and
     * safe to call from another thread than read's (the actuators' sender
     * reads it every 2 ms while a tick computes: iso_dev_hub_estop_probe).
     * 1 pressed, 0 released, ISO_ENOTSUP when the source has no e-stop
     * line, another negative ISO_E* when the read failed. NULL: none. */
    int (*estop_level)(iso_dev_source *s);
} iso_dev_source_ops;

struct iso_dev_source {
    const iso_dev_source_ops *ops;
    iso_dev_info info;
    int multiplexed; /* 1: chunks carry their own source index (replay) */
    void *impl;      /* the backend's private struct */
    /* For people, not recorded: what else says which device this is (a HID
     * product name, the socket spacenavd answered on); "" if nothing. */
    char detail[ISO_DEV_NAME_MAX];
};

ISO_API int iso_dev_source_fd(iso_dev_source *s);
ISO_API ISO_NODISCARD int iso_dev_source_read(iso_dev_source *s, int64_t until_ns,
                                              iso_dev_chunk *out, iso_err *err);
ISO_API void iso_dev_source_close(iso_dev_source *s); /* NULL is a no-op */

/* ---- simulated backends (always built) --------------------------------- */

/* A scripted source for tests: chunks and "gone" marks queued by the test,
 * handed out in order once until_ns reaches their time. */
ISO_API ISO_NODISCARD int iso_dev_fake_open(const iso_dev_info *info, iso_dev_source **out,
                                            iso_err *err);
/* Queues bytes (len <= ISO_DEV_CHUNK_MAX) at time t. */
ISO_API ISO_NODISCARD int iso_dev_fake_push(iso_dev_source *s, int64_t t_ns, const void *data,
                                            size_t len);
/* Queues a device failure at time t: read then returns ISO_EIO. */
ISO_API ISO_NODISCARD int iso_dev_fake_push_gone(iso_dev_source *s, int64_t t_ns);
/* How many times write_level was called, and the last level written. */
ISO_API int iso_dev_fake_writes(iso_dev_source *s, int *last_level);
/* Gives the fake an e-stop line at this level (1 pressed, 0 released, or a
 * negative ISO_E* its estop_level then returns); any thread. Until the first
 * call it has none (ISO_ENOTSUP). */
ISO_API void iso_dev_fake_set_estop(iso_dev_source *s, int level);

/* ---- OS backends without optional libraries (always built) ------------ */

/* A POSIX tty (pseudo-terminal, emulator, /dev/ttyUSB0) in raw 8N1 at baud. */
ISO_API ISO_NODISCARD int iso_dev_tty_open(const char *path, uint32_t baud, iso_dev_source **out,
                                           iso_err *err);
/* A TCP client to a serial-over-network bridge, "host:port". Connects before
 * it returns (timeout_ms), then reads without blocking. */
ISO_API ISO_NODISCARD int iso_dev_tcp_open(const char *host_port, int timeout_ms,
                                           iso_dev_source **out, iso_err *err);

/* ---- hardware backends (compiled when their -dev package is present) -- */
/* Each returns ISO_ENOTSUP with a sentence when its library was not built in. */

/* hidapi (hidraw): path as hidapi enumerates it ("/dev/hidraw3"), or NULL
 * for the first known 3D mouse. */
ISO_API ISO_NODISCARD int iso_dev_hid_open(const char *path, iso_dev_source **out, iso_err *err);
/* The same, held to a vendor and product id (0: any): without a path, the
 * first device with that vid (and pid); with both 0, the first known 3D
 * mouse. With a path, a device there whose ids differ is refused (ISO_EIO,
 * naming both pairs), so a scene never drives a handle from a device it did
 * not name. Not found: ISO_EIO naming the ids. */
ISO_API ISO_NODISCARD int iso_dev_hid_open_id(const char *path, uint16_t vid, uint16_t pid,
                                              iso_dev_source **out, iso_err *err);
/* spacenavd through libspnav: fails with ISO_EIO when no daemon runs. The
 * socket is found as libspnav finds it: $SPNAV_SOCKET, then `socket =` in
 * /etc/spnavrc, then /var/run/spnav.sock (the first that accepts; it goes
 * into detail). When the daemon closes the connection (stopped, killed,
 * restarted) read reports the source gone, so the hub emits GONE and
 * retries; libspnav itself would only see "no events". */
ISO_API ISO_NODISCARD int iso_dev_spnav_open(iso_dev_source **out, iso_err *err);
/* libserialport: a real serial adapter by name ("/dev/ttyUSB0"). */
ISO_API ISO_NODISCARD int iso_dev_serialport_open(const char *name, uint32_t baud,
                                                  iso_dev_source **out, iso_err *err);
/* libgpiod v1: chip ("gpiochip0"), clutch and e-stop line offsets (-1 none),
 * active_low, debounce, and an optional output line for a per-tick pulse. */
typedef struct iso_dev_gpio_opts {
    const char *chip;
    int clutch_line, estop_line, pulse_line;
    int active_low;
    uint32_t debounce_us;
} iso_dev_gpio_opts;
ISO_API ISO_NODISCARD int iso_dev_gpiod_open(const iso_dev_gpio_opts *o, iso_dev_source **out,
                                             iso_err *err);

#endif
