/* tests/test_dev_axes.c -- a 3D mouse's axes from the device to here
 * (iso_dev_axes.h): the HID descriptor walk that tells relative from absolute
 * axes and finds their range, and the spnav backend's mapping of
 * spacenavd's events back to the device's axes and counts, checked against
 * spacenavd 1.1's own arithmetic (its evdev rescale, Y/Z swap and dead
 * zone, written out here from its source's description) for every count a
 * device can send. The same paths against the real kernel and daemon run
 * in the VM group (tests/vm). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <string.h>

#include "iso_dev_axes.h"

/* A SpaceNavigator's descriptor, the later layout: unit items after the
 * ranges, relative Input items at bytes 36 and 53. */
static const uint8_t sn_units[] = {
    0x05, 0x01, 0x09, 0x08, 0xa1, 0x01, 0xa1, 0x00, 0x85, 0x01, 0x16, 0xa2, 0xfe, 0x26,
    0x5e, 0x01, 0x36, 0x88, 0xfa, 0x46, 0x78, 0x05, 0x55, 0x0c, 0x65, 0x11, 0x09, 0x30,
    0x09, 0x31, 0x09, 0x32, 0x75, 0x10, 0x95, 0x03, 0x81, 0x06, 0xc0, 0xa1, 0x00, 0x85,
    0x02, 0x09, 0x33, 0x09, 0x34, 0x09, 0x35, 0x75, 0x10, 0x95, 0x03, 0x81, 0x06, 0xc0,
    0xa1, 0x02, 0x85, 0x03, 0x05, 0x09, 0x19, 0x01, 0x29, 0x02, 0x15, 0x00, 0x25, 0x01,
    0x75, 0x01, 0x95, 0x02, 0x81, 0x02, 0x95, 0x0e, 0x81, 0x03, 0xc0, 0xc0};

static void descriptor_relative_axes_and_range(void **state)
{
    (void)state;
    iso_dev_hid_axes_info ax;
    assert_int_equal(iso_dev_hid_axes(sn_units, sizeof sn_units, &ax), ISO_OK);
    assert_int_equal(ax.found, 0x3f);
    assert_int_equal(ax.relative, 0x3f);
    assert_int_equal(ax.lo, -350);
    assert_int_equal(ax.hi, 350);
    /* Where hid-logitech's fixup would look, and what it would write. */
    assert_int_equal(sn_units[36], 0x81);
    assert_int_equal(sn_units[53], 0x81);
}

static void descriptor_absolute_axes(void **state)
{
    (void)state;
    uint8_t d[sizeof sn_units];
    memcpy(d, sn_units, sizeof d);
    d[37] = d[54] = 0x02; /* Data,Var,Abs */
    iso_dev_hid_axes_info ax;
    assert_int_equal(iso_dev_hid_axes(d, sizeof d, &ax), ISO_OK);
    assert_int_equal(ax.relative, 0);
    /* Only the rotation absolute: the bits say which. */
    d[37] = 0x06;
    assert_int_equal(iso_dev_hid_axes(d, sizeof d, &ax), ISO_OK);
    assert_int_equal(ax.relative, 0x07);
}

static void descriptor_usage_range_and_unsigned_max(void **state)
{
    (void)state;
    /* Usage Minimum X .. Maximum Rz, a range 0..1023 (a 2-byte maximum
     * whose top bit is clear either way), absolute. */
    static const uint8_t d[] = {0x05, 0x01, 0x09, 0x08, 0xa1, 0x01, 0x15, 0x00, 0x26, 0xff, 0x03,
                                0x19, 0x30, 0x29, 0x35, 0x75, 0x10, 0x95, 0x06, 0x81, 0x02, 0xc0};
    iso_dev_hid_axes_info ax;
    assert_int_equal(iso_dev_hid_axes(d, sizeof d, &ax), ISO_OK);
    assert_int_equal(ax.found, 0x3f);
    assert_int_equal(ax.relative, 0);
    assert_int_equal(ax.lo, 0);
    assert_int_equal(ax.hi, 1023);
    /* A one-byte maximum 0xff after a minimum of 0 is 255, not -1. */
    static const uint8_t e[] = {0x05, 0x01, 0x15, 0x00, 0x25, 0xff, 0x19, 0x30,
                                0x29, 0x35, 0x75, 0x08, 0x95, 0x06, 0x81, 0x02};
    assert_int_equal(iso_dev_hid_axes(e, sizeof e, &ax), ISO_OK);
    assert_int_equal(ax.hi, 255);
}

static void descriptor_without_axes_or_cut(void **state)
{
    (void)state;
    iso_dev_hid_axes_info ax;
    /* Buttons only: nothing found. */
    assert_int_equal(iso_dev_hid_axes(sn_units + 56, sizeof sn_units - 56, &ax), ISO_ENOTSUP);
    assert_int_equal(ax.found, 0);
    /* Usages on another page are not axes. */
    static const uint8_t kb[] = {0x05, 0x07, 0x09, 0x30, 0x09, 0x31, 0x81, 0x02};
    assert_int_equal(iso_dev_hid_axes(kb, sizeof kb, &ax), ISO_ENOTSUP);
    /* Cut inside an item's data. */
    assert_int_equal(iso_dev_hid_axes(sn_units, 12, &ax), ISO_EPARSE);
    /* Cut after the translation: three found. */
    assert_int_equal(iso_dev_hid_axes(sn_units, 39, &ax), ISO_ENOTSUP);
    assert_int_equal(ax.found, 0x07);
}

static void spacenavd_swaps_as_its_table_says(void **state)
{
    (void)state;
    assert_int_equal(iso_dev_spnav_swaps_yz(0x046d, 0xc626), 1); /* SpaceNavigator */
    assert_int_equal(iso_dev_spnav_swaps_yz(0x046d, 0xc62b), 1); /* SpaceMouse Pro */
    assert_int_equal(iso_dev_spnav_swaps_yz(0x256f, 0xc635), 1); /* every 256f device */
    assert_int_equal(iso_dev_spnav_swaps_yz(0x046d, 0xc603), 0); /* SpaceMouse Plus XT */
    assert_int_equal(iso_dev_spnav_swaps_yz(0x046d, 0xc621), 0); /* SpaceBall 5000 */
    assert_int_equal(iso_dev_spnav_swaps_yz(0, 0), 1);           /* not told: the usual */
}

/* spacenavd 1.1 on one evdev axis value r of device axis a: the rescale of
 * an absolute axis to [-500, 500] (integer arithmetic, r >= lo), then the
 * swap and negation of Y/Z, then the dead zone |v| < 2. */
static void spacenavd(const iso_dev_spnav_layout *l, const int dev[6], int out[6])
{
    static const int to[6] = {0, 2, 1, 3, 5, 4};
    for (int a = 0; a < 6; a++) {
        int v = dev[a];
        if (l->absolute)
            v = (v - l->lo) * 1000 / (l->hi - l->lo) - 500;
        int i = l->swap_yz ? to[a] : a;
        if (l->swap_yz && i != 0 && i != 3)
            v = -v;
        out[i] = v > -2 && v < 2 ? 0 : v;
    }
}

static void round_trip(const iso_dev_spnav_layout *l, int lo, int hi, int exact)
{
    for (int r = lo; r <= hi; r++) {
        /* each axis at r or its mirror in the range, neighbours differing,
         * so a swap cannot hide */
        const int m = lo + hi - r;
        const int dev[6] = {r, m, r, m, r, m};
        int v[6];
        spacenavd(l, dev, v);
        int16_t back[6];
        iso_dev_spnav_to_device(l, v, back);
        for (int a = 0; a < 6; a++) {
            int want = dev[a];
            int near0 = l->absolute ? (want - l->lo) * 1000 / (l->hi - l->lo) - 500 : want;
            if (near0 > -2 && near0 < 2) /* lost in spacenavd's dead zone */
                want = l->absolute ? l->lo + (int)((500LL * (l->hi - l->lo) + 999) / 1000) : 0;
            if (exact)
                assert_int_equal(back[a], want);
            else /* several counts per step: the least of them */
                assert_true(back[a] <= want && back[a] >= want - (l->hi - l->lo) / 1000 - 1);
        }
    }
}

static void spnav_back_to_device_relative(void **state)
{
    (void)state;
    iso_dev_spnav_layout l = {1, 0, 0, 0};
    round_trip(&l, -350, 350, 1);
    /* by name: spacenavd's (x, y, z) is the device's (x, -z, -y) */
    const int v[6] = {10, 20, 30, 40, 50, 60};
    int16_t d[6];
    iso_dev_spnav_to_device(&l, v, d);
    const int16_t want[6] = {10, -30, -20, 40, -60, -50};
    assert_memory_equal(d, want, sizeof want);
    l.swap_yz = 0;
    iso_dev_spnav_to_device(&l, v, d);
    const int16_t same[6] = {10, 20, 30, 40, 50, 60};
    assert_memory_equal(d, same, sizeof same);
}

static void spnav_back_to_device_absolute(void **state)
{
    (void)state;
    /* ±350: 1.43 counts of spacenavd's per device count, an exact inverse */
    iso_dev_spnav_layout l = {1, 1, -350, 350};
    round_trip(&l, -350, 350, 1);
    const int v[6] = {285, 0, 0, 0, 0, 0}; /* spacenavd's value for 200 */
    int16_t d[6];
    iso_dev_spnav_to_device(&l, v, d);
    assert_int_equal(d[0], 200);
    /* an asymmetric range, and one wider than spacenavd's 1000 steps */
    iso_dev_spnav_layout m = {0, 1, -512, 511};
    round_trip(&m, -512, 511, 0);
    iso_dev_spnav_layout n = {1, 1, 0, 255};
    round_trip(&n, 0, 255, 1);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(descriptor_relative_axes_and_range),
        cmocka_unit_test(descriptor_absolute_axes),
        cmocka_unit_test(descriptor_usage_range_and_unsigned_max),
        cmocka_unit_test(descriptor_without_axes_or_cut),
        cmocka_unit_test(spacenavd_swaps_as_its_table_says),
        cmocka_unit_test(spnav_back_to_device_relative),
        cmocka_unit_test(spnav_back_to_device_absolute),
    };
    return cmocka_run_group_tests_name("dev_axes", t, NULL, NULL);
}
