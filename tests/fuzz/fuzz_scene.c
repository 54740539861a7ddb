/* tests/fuzz/fuzz_scene.c -- libFuzzer target for the scene reader
 * (config/scene*.c): YAML in memory, parsed and validated with
 * ISO_SCENE_PARSE_ONLY (no file is opened, no mesh built). An accepted
 * scene must be self-consistent; a refused one must say why. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "iso_scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    iso_scene_opts opts = {.flags = ISO_SCENE_PARSE_ONLY};
    iso_scene *s = NULL;
    iso_err err;
    iso_err_clear(&err);
    int rc = iso_scene_load_mem((const char *)data, size, "fuzz.yaml", &opts, &s, &err);
    if (rc == ISO_OK) {
        if (!s || s->n_handles < 1 || s->n_handles > ISO_SCENE_MAX_HANDLES || !(s->tick_hz > 0) ||
            !(s->solver.omega > 0 && s->solver.omega <= 1))
            abort();
        for (int i = 0; i < s->n_devices; i++)
            if ((s->devices[i].stale_ms < ISO_SCENE_STALE_MS_MIN && s->devices[i].stale_ms != 0) ||
                s->devices[i].stale_ms > ISO_SCENE_STALE_MS_MAX) /* 0: the kind's default */
                abort();
        for (int h = 0; h < s->n_handles; h++) {
            const iso_scene_driver *d = &s->handles[h].driver;
            if (d->kind == ISO_SCENE_DRIVE_DEVICE && (d->device < 0 || d->device >= s->n_devices))
                abort();
        }
        iso_scene_destroy(s);
    } else if (s != NULL || err.msg[0] == '\0' || strlen(err.msg) >= sizeof err.msg) {
        abort();
    }
    return 0;
}
