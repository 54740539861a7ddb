/* common/iso_clock.h -- monotonic time in seconds, for phase timings and ticks. */
#ifndef ISO_CLOCK_H
#define ISO_CLOCK_H

#include "iso_api.h"

/* Seconds on CLOCK_MONOTONIC; only differences are meaningful. */
ISO_API double iso_clock_now(void);

#endif
