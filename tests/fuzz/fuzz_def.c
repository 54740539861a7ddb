/* tests/fuzz/fuzz_def.c -- libFuzzer target for the .def reader. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "regions_internal.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    double M[16];
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_def__parse("fuzz.def", data, size, M, &err);
    if (rc == ISO_OK) {
        for (int i = 0; i < 16; i++)
            if (!isfinite(M[i]))
                abort();
    } else if (err.msg[0] == '\0') {
        abort();
    }
    return 0;
}
