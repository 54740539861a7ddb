/* devices/backend_hidapi.c -- 3D mice through hidapi's hidraw backend.
 *
 * hidraw, not libusb: the kernel keeps its driver bound, so a running
 * spacenavd (which reads the evdev node) keeps working beside us. hidapi
 * exposes no descriptor to poll, so the hub reads it without blocking each
 * tick. Report descriptors come from sysfs, for the recording's header. */
#include "internal.h"
#include "iso_dev_enum.h"
#include "iso_dev_source.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef ISO_DEV_WITH_HIDAPI
#include <hidapi.h>

const int iso_dev__hidapi_built = 1;

/* hidraw keeps 64 reports per reader (HIDRAW_BUFFER_SIZE, one slot kept
 * free) and drops the newest when they are full. A 3D mouse reports every
 * 8 ms or so while deflected, so a tick slower than a quarter second (a
 * large mesh) reads a full buffer of older reports, and the newest are
 * lost: while the cap is held that only delays its state by a tick, but
 * when the lost ones hold its return to rest the handle would go on at the
 * last deflection read. A deflected device keeps reporting; a released
 * one falls silent. So a drain that found the buffer full, followed by one
 * that finds nothing at all, ends with a report of rest: a 13-byte report
 * 1 of zeros (all six axes, in any of the family's layouts). It is
 * recorded like any report, so replays agree. */
#define HIDRAW_KEEPS 63

typedef struct hid {
    hid_device *dev;
    int run;  /* reports read since the buffer was last found empty */
    int full; /* the last drain found the buffer full */
} hid;

static int hid_read_chunk(iso_dev_source *s, int64_t until, iso_dev_chunk *out, iso_err *err)
{
    (void)until;
    hid *h = s->impl;
    int n = hid_read(h->dev, out->data, ISO_DEV_CHUNK_MAX);
    if (iso_dev__chunk_read(out, n)) {
        h->run++;
        return 1;
    }
    if (n == 0) {
        int silent_after_full = h->full && h->run == 0;
        h->full = h->run >= HIDRAW_KEEPS;
        h->run = 0;
        if (!silent_after_full)
            return 0;
        memset(out->data, 0, 13);
        out->data[0] = 1;
        return iso_dev__chunk_read(out, 13);
    }
    const wchar_t *why = hid_error(h->dev);
    return iso_err_set(err, ISO_EIO, -1, "%s: %ls", s->info.name, why ? why : L"read failed");
}

static void hid_close_source(iso_dev_source *s)
{
    hid *h = s->impl;
    hid_close(h->dev);
    iso_dev__source_free(s);
}

static const iso_dev_source_ops hid_ops = {"hidapi",         NULL, hid_read_chunk, NULL,
                                           hid_close_source, NULL};

/* /dev/hidrawN -> /sys/class/hidraw/hidrawN/device/report_descriptor */
static void read_descriptor(iso_dev_info *info)
{
    const char *base = strrchr(info->name, '/');
    if (!base || strncmp(base + 1, "hidraw", 6) != 0)
        return;
    char path[256];
    snprintf(path, sizeof path, "/sys/class/hidraw/%s/device/report_descriptor", base + 1);
    FILE *f = fopen(path, "rb");
    if (!f)
        return;
    info->desc_len = (uint16_t)fread(info->desc, 1, ISO_DEV_DESC_MAX, f);
    fclose(f);
}

/* Whether hidapi's entry d is the device asked for: at path, or (without
 * one) with the ids, or (without ids either) a known 3D mouse. */
static int wanted(const struct hid_device_info *d, const char *path, uint16_t vid, uint16_t pid)
{
    if (path)
        return strcmp(d->path, path) == 0;
    if (vid)
        return d->vendor_id == vid && (!pid || d->product_id == pid);
    return iso_dev_is_3dmouse(d->vendor_id, d->product_id);
}

int iso_dev_hid_open(const char *path, iso_dev_source **out, iso_err *err)
{
    return iso_dev_hid_open_id(path, 0, 0, out, err);
}

int iso_dev_hid_open_id(const char *path, uint16_t want_vid, uint16_t want_pid,
                        iso_dev_source **out, iso_err *err)
{
    *out = NULL;
    if (hid_init() != 0)
        return iso_err_set(err, ISO_EIO, -1, "hidapi: cannot initialise");
    char found[ISO_DEV_NAME_MAX] = "";
    char product[ISO_DEV_NAME_MAX] = "";
    uint16_t vid = 0, pid = 0;
    struct hid_device_info *all = hid_enumerate(0, 0);
    for (struct hid_device_info *d = all; d; d = d->next) {
        if (wanted(d, path, want_vid, want_pid)) {
            snprintf(found, sizeof found, "%s", d->path);
            vid = d->vendor_id;
            pid = d->product_id;
            /* %ls fails on a name the C locale cannot spell: keep none. */
            if (!d->product_string ||
                snprintf(product, sizeof product, "%ls", d->product_string) < 0)
                product[0] = '\0';
            break;
        }
    }
    hid_free_enumeration(all);
    if (!found[0] && !path && !want_vid)
        return iso_err_set(err, ISO_EIO, -1,
                           "no 3D mouse found (3Dconnexion 046d or 256f): is it plugged in?");
    if (!found[0] && !path)
        return iso_err_set(err, ISO_EIO, -1, "no HID device %04x:%04x found: is it plugged in?",
                           want_vid, want_pid);
    if (found[0] && ((want_vid && vid != want_vid) || (want_pid && pid != want_pid)))
        return iso_err_set(err, ISO_EIO, -1,
                           "%s is %04x:%04x, not the %04x:%04x the caller asked for", found, vid,
                           pid, want_vid, want_pid);
    const char *p = found[0] ? found : path;
    hid_device *dev = hid_open_path(p);
    if (!dev) {
        int e = errno;
        return iso_err_set(err, ISO_EIO, -1, "%s: cannot open%s%s", p, e ? ": " : "",
                           e ? strerror(e) : "");
    }
    hid_set_nonblocking(dev, 1);
    iso_dev_source *s = iso_dev__source_new(&hid_ops, sizeof(hid));
    if (!s) {
        hid_close(dev);
        return iso_err_set(err, ISO_ENOMEM, -1, "%s: out of memory", p);
    }
    hid *h = s->impl;
    h->dev = dev;
    s->info.kind = ISO_DEV_KIND_HID;
    s->info.vid = vid;
    s->info.pid = pid;
    snprintf(s->info.name, sizeof s->info.name, "%s", p);
    memcpy(s->detail, product, sizeof s->detail);
    read_descriptor(&s->info);
    *out = s;
    return ISO_OK;
}

/* 1 if one of the first n entries already lists path. */
static int listed(const iso_dev_found *out, size_t n, const char *path)
{
    for (size_t i = 0; i < n; i++)
        if (strcmp(out[i].path, path) == 0)
            return 1;
    return 0;
}

size_t iso_dev__hid_enumerate(iso_dev_found *out, size_t cap)
{
    size_t n = 0;
    if (hid_init() != 0)
        return 0;
    /* hidapi's hidraw backend (0.13) lists a device once per collection
     * its report descriptor gives a usage, nested ones included: a
     * SpaceNavigator comes three times (multi-axis controller, its vendor
     * collection and the feature collection inside it) with one path. It
     * is one device and one hidraw node to open. */
    struct hid_device_info *all = hid_enumerate(0, 0);
    for (struct hid_device_info *d = all; d && n < cap; d = d->next) {
        if (!iso_dev_is_3dmouse(d->vendor_id, d->product_id) || listed(out, n, d->path))
            continue;
        iso_dev_found *f = &out[n++];
        memset(f, 0, sizeof *f);
        snprintf(f->backend, sizeof f->backend, "hidapi");
        snprintf(f->path, sizeof f->path, "%s", d->path);
        snprintf(f->what, sizeof f->what, "%ls %ls",
                 d->manufacturer_string ? d->manufacturer_string : L"",
                 d->product_string ? d->product_string : L"3D mouse");
        f->vid = d->vendor_id;
        f->pid = d->product_id;
        hid_device *dev = hid_open_path(d->path);
        f->usable = dev != NULL;
        if (dev) {
            hid_close(dev);
        } else {
            char rule[160];
            iso_dev_udev_rule(d->vendor_id, rule, sizeof rule);
            snprintf(f->why, sizeof f->why,
                     "cannot open %s (%s): add the udev rule '%s' to "
                     "/etc/udev/rules.d/69-3dconnexion.rules, then run 'udevadm control "
                     "--reload && udevadm trigger' and replug",
                     d->path, errno ? strerror(errno) : "permission", rule);
        }
    }
    hid_free_enumeration(all);
    return n;
}

#else

const int iso_dev__hidapi_built = 0;

int iso_dev_hid_open(const char *path, iso_dev_source **out, iso_err *err)
{
    return iso_dev_hid_open_id(path, 0, 0, out, err);
}

int iso_dev_hid_open_id(const char *path, uint16_t vid, uint16_t pid, iso_dev_source **out,
                        iso_err *err)
{
    (void)vid;
    (void)pid;
    *out = NULL;
    return iso_err_set(err, ISO_ENOTSUP, -1,
                       "%s: this build has no hidapi backend (install libhidapi-dev and rebuild)",
                       path ? path : "3D mouse");
}

size_t iso_dev__hid_enumerate(iso_dev_found *out, size_t cap)
{
    (void)out;
    (void)cap;
    return 0;
}
#endif
