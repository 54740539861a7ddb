/* firmware-bridge/iso_fb_mcu.h -- the microcontroller's side of the link:
 * message handling, the per-channel actuator model (position limits, rate
 * limit, safe state) and the link watchdog, as plain logic driven by bytes
 * in and a millisecond clock. The firmware wraps it in a UART driver and a
 * SysTick; the host tests drive it directly, so one source is tested twice.
 *
 * Freestanding C11 like iso_fb.c: no malloc, no stdio, no globals. */
#ifndef ISO_FB_MCU_H
#define ISO_FB_MCU_H

#include "iso_fb.h"

#define ISO_FB_MCU_FW_VERSION 0x0101u /* 1.1: obeys SAFE */

/* The bridge board's serial line: the firmware's UART runs at this rate,
 * and a host link to it opens at it unless told otherwise. */
#define ISO_FB_BOARD_BAUD 115200u

/* Sends bytes towards the host; must take them all (the firmware queues
 * them in its UART ring). */
typedef void (*iso_fb_mcu_write_fn)(void *ctx, const uint8_t *bytes, size_t n);

typedef struct iso_fb_mcu_config {
    uint8_t n_channels; /* 1..ISO_FB_MAX_CHANNELS */
    iso_fb_channel_info ch[ISO_FB_MAX_CHANNELS];
    uint32_t watchdog_ms;  /* no SETPOINTS this long -> safe state; default 100 */
    uint32_t heartbeat_ms; /* HEARTBEAT period; default 100 */
    uint32_t sample_ms;    /* HANDLE_SAMPLE period while armed; 0 = off; default 20 */
} iso_fb_mcu_config;

typedef struct iso_fb_mcu {
    iso_fb_mcu_config cfg;
    iso_fb_parser parser;
    iso_fb_mcu_write_fn write;
    void *write_ctx;
    uint16_t tx_seq;
    uint8_t state;          /* ISO_FB_STATE_* */
    uint8_t hang_requested; /* DIAG asked to stop feeding the hardware watchdog */
    uint32_t now_ms;
    uint32_t last_setpoints_ms, last_heartbeat_ms, last_sample_ms;
    int32_t pos_u[ISO_FB_MAX_CHANNELS];    /* positions in micro-units */
    int32_t target_u[ISO_FB_MAX_CHANNELS]; /* rate-limited towards these */
    uint32_t setpoints_applied, clamped, naks, faults;
} iso_fb_mcu;

/* Fills a config with n channels of limits [-1000, 1000], rate 2000/s,
 * safe position 0, and the default periods. */
ISO_API void iso_fb_mcu_config_default(iso_fb_mcu_config *cfg, uint8_t n_channels);

/* The bridge board's configuration, the one the firmware runs
 * (firmware/main.c) and the native emulation runs in its place, so that both
 * answer HELLO alike: 4 channels with the defaults above, except channel 1
 * at [-1500, 1500], channel 2 at 500/s and channel 3 at [0, 2000]. */
ISO_API void iso_fb_mcu_config_board(iso_fb_mcu_config *cfg);

/* Starts the node in the IDLE state (every channel at its safe position) and
 * announces it with an unasked HELLO carrying ISO_FB_HELLO_BOOT. Returns 0 or
 * ISO_FB_EARG for a bad config. */
ISO_API int iso_fb_mcu_init(iso_fb_mcu *m, const iso_fb_mcu_config *cfg, iso_fb_mcu_write_fn write,
                            void *write_ctx, uint32_t now_ms);

/* Feeds received bytes; complete frames are handled at once (replies are
 * written through the write callback). */
ISO_API void iso_fb_mcu_rx(iso_fb_mcu *m, const uint8_t *bytes, size_t n);

/* Advances the clock to now_ms (wraps after 49 days; differences are taken
 * modulo 2^32): moves actuators, runs the link watchdog, sends HEARTBEAT and
 * HANDLE_SAMPLE when due. Call at least every millisecond for the watchdog to
 * hold its "watchdog time plus one frame" bound. */
ISO_API void iso_fb_mcu_tick(iso_fb_mcu *m, uint32_t now_ms);

/* Current position of channel ch in milli-units (rounded toward zero). */
ISO_API int16_t iso_fb_mcu_position(const iso_fb_mcu *m, unsigned ch);

/* The simulated sensor on the MCU: a deterministic pose as a function of its
 * timestamp, so tests on the host can check every decoded sample. */
ISO_API void iso_fb_mcu_synth_sample(uint32_t t_us, iso_fb_sample *out);

#endif
