/* tests/fuzz/fuzz_sel.c -- libFuzzer target for the .sel reader. The first
 * byte is the vertex count the caller expects (0..255); the rest is the file. */
#include <stdint.h>
#include <stdlib.h>

#include "regions_internal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0)
        return 0;
    iso_regions r;
    iso_err err;
    iso_err_clear(&err);
    int nv = data[0];
    int rc = iso_sel__parse("fuzz.sel", data + 1, size - 1, nv, &r, &err);
    if (rc == ISO_OK) {
        for (int i = 0; i < nv; i++)
            if (r.kind[i] > ISO_HANDLE || (r.kind[i] == ISO_HANDLE) != (r.handle[i] == 0))
                abort();
        iso_regions_deinit(&r);
    } else if (r.kind != NULL || err.msg[0] == '\0') {
        abort();
    }
    return 0;
}
