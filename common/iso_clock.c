/* common/iso_clock.c -- see iso_clock.h. */
#define _POSIX_C_SOURCE 200809L
#include "iso_clock.h"

#include <errno.h>
#include <time.h>

int64_t iso_clock_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

uint64_t iso_clock_us(void)
{
    return (uint64_t)(iso_clock_ns() / 1000);
}

double iso_clock_now(void)
{
    return 1e-9 * (double)iso_clock_ns();
}

int iso_clock_ms_until(uint64_t deadline_us)
{
    uint64_t now = iso_clock_us();
    return now >= deadline_us ? 0 : (int)((deadline_us - now + 999u) / 1000u);
}

int iso_clock_sleep_until(int64_t deadline_ns)
{
    if (deadline_ns < 0)
        deadline_ns = 0;
    struct timespec ts = {(time_t)(deadline_ns / 1000000000), (long)(deadline_ns % 1000000000)};
    return clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR ? 1 : 0;
}
