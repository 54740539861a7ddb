/* tests/fuzz/fuzz_dev_rec.c -- the recording reader (devices/recording.c)
 * on arbitrary files: the header parse, then every record, with the reader's
 * promises checked: it stays inside the data, hands out only records that
 * fit a chunk and name a source of the header, and ends torn or clean. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    iso_dev_rec_reader r;
    iso_err err;
    iso_err_clear(&err);
    if (iso_dev_rec_reader_init(&r, data, size, &err) != ISO_OK) {
        if (err.code != ISO_EPARSE && err.code != ISO_ENOMEM)
            abort();
        return 0;
    }
    iso_dev_chunk c;
    long n = 0;
    while (iso_dev_rec_next(&r, &c, NULL) == 1) {
        n++;
        if (c.len > ISO_DEV_CHUNK_MAX || r.pos > size ||
            (c.type != ISO_DEV_CHUNK_TICK && c.source >= r.n_sources))
            abort();
    }
    if (n != r.records || r.end_at > (long)size || (r.torn && !r.note[0]))
        abort();
    /* a second reader over the same bytes reads the same */
    iso_dev_rec_reader r2;
    if (iso_dev_rec_reader_init(&r2, data, size, NULL) != ISO_OK)
        abort();
    while (iso_dev_rec_next(&r2, &c, NULL) == 1)
        ;
    if (r2.records != r.records || r2.damaged != r.damaged || r2.torn != r.torn)
        abort();
    iso_dev_rec_reader_deinit(&r2);
    iso_dev_rec_reader_deinit(&r);
    return 0;
}
