/* tests/replay_fast.h -- a scene file run through the loop at --fast, no
 * view, its notices to /dev/null: what the late-tick and late-drag tests
 * compare replays by. Fails the test (with `what` and the error) when the
 * scene does not load or the run stops on an error. Header-only: the tests
 * that use it link the shared library or its static form, and testutil
 * links neither. */
#ifndef ISO_TEST_REPLAY_FAST_H
#define ISO_TEST_REPLAY_FAST_H

#include <stdio.h>

#include "iso_loop.h"
#include "iso_scene.h"
#include "testutil.h"

/* As replay_fast, with iso_loop_opts.on_tick = on_tick (ctx its context). */
static inline void replay_fast_hooked(const char *path, const char *what, iso_loop_summary *s,
                                      void (*on_tick)(void *, const iso_loop_tick_info *),
                                      void *ctx)
{
    iso_scene *sc = NULL;
    iso_err err;
    iso_err_clear(&err);
    if (iso_scene_load(path, &sc, &err) != ISO_OK)
        fail_msg("%s: %s", path, err.msg);
    iso_loop_opts o;
    iso_loop_opts_default(&o);
    o.fast = 1;
    o.display = 0;
    o.on_tick = on_tick;
    o.hook_ctx = ctx;
    FILE *quiet = fopen("/dev/null", "w");
    o.log = quiet;
    iso_loop *l = NULL;
    if (iso_loop_create(sc, &o, &l, &err) != ISO_OK || iso_loop_run(l, &err) != ISO_OK)
        fail_msg("replay of %s: %s", what, err.msg);
    iso_loop_get_summary(l, s);
    iso_loop_destroy(l);
    iso_scene_destroy(sc);
    if (quiet)
        fclose(quiet);
}

static inline void replay_fast(const char *path, const char *what, iso_loop_summary *s)
{
    replay_fast_hooked(path, what, s, NULL, NULL);
}

#endif
