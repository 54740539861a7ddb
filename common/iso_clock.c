/* common/iso_clock.c -- see iso_clock.h. */
#define _POSIX_C_SOURCE 200809L
#include "iso_clock.h"

#include <time.h>

double iso_clock_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
