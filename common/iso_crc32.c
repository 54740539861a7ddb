/* common/iso_crc32.c -- CRC-32 (iso_crc32.h). */
#include "iso_crc32.h"

#define ISO_CRC32_POLY 0xEDB88320u

uint32_t iso_crc32_small(uint32_t crc, const void *p, size_t n)
{
    /* the bitwise CRC of each nibble, as a table (the check value test holds it) */
    static const uint32_t nib[16] = {0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu,
                                     0x76DC4190u, 0x6B6B51F4u, 0x4DB26158u, 0x5005713Cu,
                                     0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
                                     0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu};
    const unsigned char *b = p;
    uint32_t c = ~crc;
    for (size_t i = 0; i < n; i++) {
        c ^= b[i];
        c = (c >> 4) ^ nib[c & 15u];
        c = (c >> 4) ^ nib[c & 15u];
    }
    return ~c;
}

void iso_crc32_table_init(iso_crc32_table *tab)
{
    for (uint32_t i = 0; i < 256; i++) {
        uint32_t c = i;
        for (int k = 0; k < 8; k++)
            c = c & 1u ? ISO_CRC32_POLY ^ (c >> 1) : c >> 1;
        tab->t[0][i] = c;
    }
    for (int k = 1; k < 8; k++)
        for (int i = 0; i < 256; i++) {
            uint32_t c = tab->t[k - 1][i];
            tab->t[k][i] = (c >> 8) ^ tab->t[0][c & 0xffu];
        }
}

/* Four bytes as the register sees them: the first in the low bits. Built
 * from bytes, so the order is the same on any host. */
static uint32_t le32(const unsigned char *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

uint32_t iso_crc32_fast(const iso_crc32_table *tab, uint32_t crc, const void *p, size_t n)
{
    const uint32_t(*t)[256] = tab->t;
    const unsigned char *b = p;
    uint32_t c = ~crc;
    for (; n >= 8; n -= 8, b += 8) {
        uint32_t lo = c ^ le32(b), hi = le32(b + 4);
        c = t[7][lo & 0xffu] ^ t[6][(lo >> 8) & 0xffu] ^ t[5][(lo >> 16) & 0xffu] ^ t[4][lo >> 24] ^
            t[3][hi & 0xffu] ^ t[2][(hi >> 8) & 0xffu] ^ t[1][(hi >> 16) & 0xffu] ^ t[0][hi >> 24];
    }
    for (; n > 0; n--, b++)
        c = t[0][(c ^ *b) & 0xffu] ^ (c >> 8);
    return ~c;
}
