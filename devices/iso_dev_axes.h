/* devices/iso_dev_axes.h -- a 3D mouse's axes, from the device to here:
 * what a HID report descriptor says of them, and how spacenavd changed
 * them and how that is undone, so that every backend hands on the
 * device's own axes and a scene maps a device the same through any of
 * them. Pure functions on numbers, apart from sources and decoders: the
 * backends call them (hid_desc.c, backend_spnav.c) and tests check them
 * alone. */
#ifndef ISO_DEV_AXES_H
#define ISO_DEV_AXES_H

#include <stddef.h>
#include <stdint.h>

#include "iso_err.h" /* iso_dev_hid_axes returns its codes */

/* ---- a 3D mouse's axes, from the device to here ------------------------
 * The axes this library hands on (ISO_DEV_EV_AXES, and so every mapping)
 * are the device's own: its HID report's X Y Z Rx Ry Rz, in its counts
 * (about ±350 on the 3Dconnexion family), from either backend:
 *  - hidraw (hidapi) gives the report's bytes, whatever the kernel makes
 *    of the device for evdev (the same bytes in every layout below). It
 *    keeps 63 reports per reader and drops the newest when full: a tick
 *    slower than that lasts (about 0.25 s at a mouse's 125 reports a
 *    second) can lose the cap's return to rest. A deflected device keeps
 *    reporting, a released one falls silent: so a drain that found the
 *    buffer full, followed by one that finds nothing, ends with a report of
 *    rest (13 bytes, ID 1, zeros);
 *  - spacenavd reads evdev and changes the axes; the spnav backend undoes
 *    it (iso_dev_spnav_to_device), so a scene maps a device the same
 *    through either. What spacenavd (1.1) does, and what the kernel
 *    (6.1) does before it:
 *    Y/Z: for the 3Dconnexion devices it knows (every 256f one, and
 *    046d:c623 c625 c626 c627 c628 c629 c62b) it swaps Y and Z and negates
 *    both, rotations as translations: its (x, y, z) is the device's
 *    (x, -z, -y).
 *    Absolute axes (evdev ABS_X..ABS_RZ: a descriptor whose axes are
 *    absolute, and the SpaceNavigator whose relative descriptor
 *    hid-logitech fixes up, the one without unit items) are rescaled from
 *    the logical range to [-500, 500]: 1.43 times the counts for ±350.
 *    Relative ones (REL_*) pass as they are.
 *    Relative axes never return to 0: the kernel passes no zero relative
 *    value, so spacenavd keeps each axis's last non-zero one and sends it
 *    again with the next event of any axis. A deflected device reports
 *    every poll, so silence means the cap is at rest: after
 *    ISO_DEV_SPNAV_REST_NS without motion (reads that find none for that
 *    long, or spacenavd's period on the next motion, whichever tells
 *    first) the backend reports rest itself (a recorded 'M' record of
 *    zeros, before that next motion), and from then on takes an axis
 *    that still shows the value spacenavd kept as 0, until it changes.
 *    Values spacenavd kept from before the connection cannot be told.
 *    spacenavd's dead zone (|v| < 2 is 0), its sensitivity and any
 *    remapping in /etc/spnavrc stay in effect.
 * Which device and layout spacenavd serves comes from the daemon
 * (protocol 1: its USB id and evdev node) or, when it does not say, from
 * the one 3D mouse among the input devices, and from sysfs (the node's
 * axis capabilities, the HID descriptor's range); without them the
 * backend assumes a swapping device with relative axes, which fails safe
 * (a rest inferred too early stops motion; one never inferred would not).
 * hidapi (0.13) lists a device once per collection that has a usage: a
 * SpaceNavigator's hidraw node three times. It is one device: isoshape
 * devices lists it once. */

/* The six axes' Input items in a HID report descriptor. */
typedef struct iso_dev_hid_axes_info {
    uint8_t found;    /* bit per axis X..Rz (0..5) an Input item carries */
    uint8_t relative; /* bit per axis whose Input item says relative */
    int32_t lo, hi;   /* the axes' logical range (the last axis item's) */
} iso_dev_hid_axes_info;
/* Walks a report descriptor. ISO_OK when all six axes were found,
 * ISO_ENOTSUP when not (out says which were), ISO_EPARSE for an item that
 * runs past len. */
ISO_API int iso_dev_hid_axes(const uint8_t *desc, size_t len, iso_dev_hid_axes_info *out);

#define ISO_DEV_SPNAV_REST_NS 200000000LL /* silence that means rest (relative axes) */

/* How spacenavd changed a device's axes (see above). */
typedef struct iso_dev_spnav_layout {
    int swap_yz;    /* 1: Y and Z swapped and negated */
    int absolute;   /* 1: rescaled from [lo, hi] to [-500, 500]; 0: as they were */
    int32_t lo, hi; /* the device's logical range (absolute only; hi > lo) */
} iso_dev_spnav_layout;
/* 1 if spacenavd 1.1 swaps and negates Y/Z for this USB id; vid 0 (the
 * daemon did not say) counts as swapping, as nearly every device does. */
ISO_API int iso_dev_spnav_swaps_yz(uint16_t vid, uint16_t pid);
/* One spacenavd motion event (x y z rx ry rz) back to the device's axes and
 * counts: the exact inverse of spacenavd's integer rescale, then of the
 * swap; clamped to int16. */
ISO_API void iso_dev_spnav_to_device(const iso_dev_spnav_layout *l, const int v[6], int16_t out[6]);

#endif
