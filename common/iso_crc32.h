/* common/iso_crc32.h -- CRC-32 as recordings and MCAP files carry it (IEEE
 * 802.3: reflected polynomial 0xEDB88320, register and result inverted;
 * the check value of "123456789" is 0xCBF43926).
 *
 * Two ways to the same value. iso_crc32_small takes four bits a step from
 * a 16-entry constant table: no setup, for short records. iso_crc32_fast
 * takes eight bytes a step from eight 256-entry tables (slicing by eight)
 * that the caller owns and fills once: an MCAP writer checksums every
 * record twice (the chunk's records, then the file's bytes), about 280 MB
 * for the README's demo, and a byte at a time that was 2% of a live run's
 * CPU. Both continue a running CRC: pass 0 to start, then what the last
 * call returned. Internal to the library: not installed, not exported. */
#ifndef ISO_CRC32_H
#define ISO_CRC32_H

#include <stddef.h>
#include <stdint.h>

typedef struct iso_crc32_table {
    uint32_t t[8][256]; /* t[0]: one byte; t[k]: a byte followed by k zero bytes */
} iso_crc32_table;

void iso_crc32_table_init(iso_crc32_table *tab);

uint32_t iso_crc32_small(uint32_t crc, const void *p, size_t n);
uint32_t iso_crc32_fast(const iso_crc32_table *tab, uint32_t crc, const void *p, size_t n);

#endif
