/* tests/fuzz/fuzz_dev_rec.c -- the recording reader (devices/recording.c)
 * on arbitrary files: the header parse, then every record, with the reader's
 * promises checked: it stays inside the data, hands out only records that
 * fit a chunk and name a source of the header, and ends torn or clean;
 * every record goes through its source's decoder (SKIP records included);
 * the cut check (iso_dev_rec_reader_cut) agrees with the reader. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "iso_dev_decode.h"
#include "iso_dev_rec.h"

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
    static iso_dev_decoder dec[ISO_DEV_MAX_SOURCES];
    static iso_dev_event ev[ISO_DEV_EVENTS_PER_CHUNK];
    int can[ISO_DEV_MAX_SOURCES] = {0};
    for (size_t i = 0; i < r.n_sources; i++)
        can[i] = iso_dev_decoder_init(&dec[i], &r.infos[i], (uint8_t)i, NULL) == ISO_OK;
    char msg[400];
    long at = -1;
    int cut = iso_dev_rec_reader_cut(&r, msg, sizeof msg, &at);
    if ((cut != 0) != (msg[0] != 0) || at < 0 || at > (long)size)
        abort();
    iso_dev_chunk c;
    long n = 0;
    while (iso_dev_rec_next(&r, &c, NULL) == 1) {
        n++;
        if (c.len > ISO_DEV_CHUNK_MAX || r.pos > size || c.type == ISO_DEV_CHUNK_END ||
            (c.type != ISO_DEV_CHUNK_TICK && c.source >= r.n_sources))
            abort();
        if (c.type != ISO_DEV_CHUNK_TICK && can[c.source] &&
            iso_dev_decode(&dec[c.source], &c, ev, ISO_DEV_EVENTS_PER_CHUNK) >
                ISO_DEV_EVENTS_PER_CHUNK)
            abort();
    }
    if (n != r.records || r.end_at > (long)size || (r.torn && !r.note[0]) || (r.torn && !cut) ||
        (r.ended && cut))
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
