/* actuators/act_internal.h -- what the actuator sink (actuators.c) asks of its
 * emulated link (emu_firmware.c); not installed. */
#ifndef ISO_ACT_INTERNAL_H
#define ISO_ACT_INTERNAL_H

#include "iso_err.h"
#include "iso_link.h"

/* 1 when l came from iso_act_emu_open(). */
int iso_act__emu_is(const iso_link *l);
/* Times the emulation was relaunched after it died; any thread. */
unsigned iso_act__emu_restarts(const iso_link *l);
/* See iso_actuators_emu_signal(); any thread. */
int iso_act__emu_signal(iso_link *l, int sig, iso_err *err);

#endif
