/* firmware-bridge/internal.h -- cross-file helpers of the host side; not
 * installed. */
#ifndef ISO_FB_INTERNAL_H
#define ISO_FB_INTERNAL_H

#include <stdint.h>

#include "iso_clock.h"
#include "iso_link.h"

#endif
