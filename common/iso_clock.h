/* common/iso_clock.h -- the monotonic clock and the one way to sleep on it.
 *
 * Every part reads time here (CLOCK_MONOTONIC: only differences mean
 * anything) and sleeps to absolute deadlines here, so a period is measured
 * from deadline to deadline and never drifts by the time a wake-up took. */
#ifndef ISO_CLOCK_H
#define ISO_CLOCK_H

#include <stdint.h>

#include "iso_api.h"

/* Nanoseconds on CLOCK_MONOTONIC. */
ISO_API int64_t iso_clock_ns(void);
/* The same in microseconds and in seconds. */
ISO_API uint64_t iso_clock_us(void);
ISO_API double iso_clock_now(void);
/* Milliseconds from now until deadline_us (iso_clock_us's scale), rounded
 * up so that a poll() for it never wakes early; 0 once it has passed. */
ISO_API int iso_clock_ms_until(uint64_t deadline_us);

/* Sleeps until iso_clock_ns() reaches deadline_ns (at once when it has).
 * Returns 0 at the deadline, or 1 when a signal woke it first (the caller
 * decides whether to sleep again). */
ISO_API int iso_clock_sleep_until(int64_t deadline_ns);

#endif
