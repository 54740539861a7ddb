/* actuators/iso_actuators_drill.h -- what the tests do to the emulated MCU
 * to prove the sink's safety rules: kill it, pause it, resume it. Internal
 * to the library's parts and its white-box tests (not installed, not
 * exported): a program never needs to hurt its own MCU. */
#ifndef ISO_ACTUATORS_DRILL_H
#define ISO_ACTUATORS_DRILL_H

#include "iso_actuators.h"

/* Sends sig to the emulated MCU. QEMU: the signal
 * goes to its process (SIGKILL, SIGSTOP, SIGCONT, ...). Native: SIGKILL
 * ends the MCU thread and closes its end of the socket pair (as a dying process
 * closes its UART), SIGSTOP pauses its clock and I/O, SIGCONT resumes.
 * ISO_EINVAL without an emulated link or for another signal (native). */
ISO_NODISCARD int iso_actuators_emu_signal(iso_actuators *a, int sig, iso_err *err);

#endif
