/* tests/fuzz/fuzz_dev_hid.c -- the hid decoder (devices/decode.c) on
 * arbitrary chunks. Input: a sequence of [head][bytes]: head & 0x7f is the
 * chunk length (cut at the end of the input), head & 0x80 marks a GONE
 * chunk instead, and the head's low nibble advances the clock. The whole
 * input is decoded twice: the events must be the same (determinism). */
#include "fuzz_dev_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return iso_fuzz_dev_decoder(ISO_DEV_KIND_HID, data, size);
}
