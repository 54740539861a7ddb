/* devices/hid_desc.c -- what a 3D mouse's HID report descriptor says about
 * its six axes: relative or absolute Input items, and their logical range.
 * A walk over the descriptor's short items (HID 1.11, 6.2.2), keeping the
 * global items in force and the usages of the Main item to come. */
#include "iso_dev_axes.h"

#include <string.h>

/* The item's data, as unsigned and as signed (two's complement of its size). */
static uint32_t item_u(const uint8_t *p, int n)
{
    uint32_t v = 0;
    for (int i = n - 1; i >= 0; i--)
        v = v << 8 | p[i];
    return v;
}

static int32_t item_s(const uint8_t *p, int n)
{
    uint32_t v = item_u(p, n);
    if (n == 1)
        return (int8_t)v;
    if (n == 2)
        return (int16_t)v;
    return (int32_t)v;
}

int iso_dev_hid_axes(const uint8_t *desc, size_t len, iso_dev_hid_axes_info *out)
{
    memset(out, 0, sizeof *out);
    uint32_t page = 0;
    int32_t lo = 0;
    const uint8_t *hi_p = NULL;
    int hi_n = 0, axes = 0; /* bit per axis X..Rz among the pending usages */
    uint32_t umin = 0;
    size_t i = 0;
    while (i < len) {
        uint8_t b = desc[i];
        if (b == 0xfe) { /* a long item: skipped whole */
            if (i + 2 >= len)
                return ISO_EPARSE;
            i += 3u + desc[i + 1];
            continue;
        }
        int n = (b & 3) == 3 ? 4 : (b & 3);
        if (i + 1 + (size_t)n > len)
            return ISO_EPARSE;
        const uint8_t *d = desc + i + 1;
        switch (b & 0xfc) {
        case 0x04: page = item_u(d, n); break; /* Usage Page */
        case 0x14: lo = item_s(d, n); break;   /* Logical Minimum */
        case 0x24: hi_p = d, hi_n = n; break;  /* Logical Maximum */
        case 0x08: {                           /* Usage */
            uint32_t u = item_u(d, n), pg = n == 4 ? u >> 16 : page;
            u &= n == 4 ? 0xffffu : 0xffffffffu;
            if (pg == 0x01 && u >= 0x30 && u <= 0x35)
                axes |= 1 << (u - 0x30);
            break;
        }
        case 0x18: umin = item_u(d, n); break; /* Usage Minimum */
        case 0x28:                             /* Usage Maximum */
            for (uint32_t u = umin; page == 0x01 && u <= item_u(d, n) && u <= 0x35; u++)
                if (u >= 0x30)
                    axes |= 1 << (u - 0x30);
            break;
        case 0x80: /* Input */
            if (axes) {
                /* Logical Maximum is signed when the minimum is negative. */
                int32_t hi = hi_p ? item_s(hi_p, hi_n) : 0;
                if (hi_p && hi < lo)
                    hi = (int32_t)item_u(hi_p, hi_n);
                out->found |= axes;
                out->relative |= (n ? d[0] & 4 : 0) ? axes : 0;
                out->lo = lo;
                out->hi = hi;
            }
            axes = 0;
            break;
        case 0x90:    /* Output */
        case 0xb0:    /* Feature */
        case 0xa0:    /* Collection */
        case 0xc0:    /* End Collection */
            axes = 0; /* local items last until the next Main item */
            break;
        default: break;
        }
        i += 1u + (size_t)n;
    }
    return out->found == 0x3f ? ISO_OK : ISO_ENOTSUP;
}
