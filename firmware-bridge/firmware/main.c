/* firmware-bridge/firmware/main.c -- the bridge firmware: interrupt-driven
 * UART0 with ring buffers, a 1 kHz SysTick, the hardware watchdog, and the
 * shared iso_fb_mcu logic in the main loop.
 *
 * The ISR-shared state sits in one static struct (the only mutable
 * file-scope state in the firmware; the protocol library has none). */
#include "board.h"
#include "iso_fb_mcu.h"

#define RING_SIZE 512u /* power of two */
_Static_assert((RING_SIZE & (RING_SIZE - 1u)) == 0, "ring size is a power of two");
_Static_assert(RING_SIZE >= 2u * ISO_FB_FRAME_MAX, "a ring holds two whole frames");

typedef struct ring {
    volatile uint16_t head, tail; /* head: producer, tail: consumer */
    uint8_t buf[RING_SIZE];
} ring;

static struct fw {
    ring rx, tx;
    volatile uint32_t ms;
    volatile uint32_t rx_dropped;
    iso_fb_mcu node;
} fw;

static int ring_put(ring *r, uint8_t b)
{
    uint16_t h = r->head;
    if ((uint16_t)(h - r->tail) >= RING_SIZE)
        return 0;
    r->buf[h & (RING_SIZE - 1u)] = b;
    r->head = (uint16_t)(h + 1u);
    return 1;
}

static int ring_get(ring *r, uint8_t *b)
{
    uint16_t t = r->tail;
    if (t == r->head)
        return 0;
    *b = r->buf[t & (RING_SIZE - 1u)];
    r->tail = (uint16_t)(t + 1u);
    return 1;
}

/* ---- interrupts ---------------------------------------------------------- */
void SysTick_Handler(void)
{
    fw.ms++;
}

void uart0_rx_isr(void)
{
    /* Clear first, then drain: a byte landing after the last STATE read
     * raises the interrupt again instead of being stranded. */
    UART_INTCLR(UART0_BASE) = UART_INT_RX;
    while (UART_STATE(UART0_BASE) & UART_STATE_RXFULL) {
        uint8_t b = (uint8_t)UART_DATA(UART0_BASE);
        if (!ring_put(&fw.rx, b))
            fw.rx_dropped++; /* the parser resynchronises at the next 0x00 */
    }
}

static void tx_next(void)
{
    uint8_t b;
    if (!(UART_STATE(UART0_BASE) & UART_STATE_TXFULL) && ring_get(&fw.tx, &b))
        UART_DATA(UART0_BASE) = b;
}

void uart0_tx_isr(void)
{
    UART_INTCLR(UART0_BASE) = UART_INT_TX;
    tx_next();
}

/* First expiry of the hardware watchdog. Leaving its interrupt pending lets
 * the second expiry reset the chip; a live main loop never gets here. */
void NMI_Handler(void)
{
}

/* ---- drivers ------------------------------------------------------------- */
static void uart_init(void)
{
    UART_BAUDDIV(UART0_BASE) = BOARD_SYSCLK_HZ / ISO_FB_BOARD_BAUD;
    UART_CTRL(UART0_BASE) = UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_TXINT | UART_CTRL_RXINT;
    NVIC_ISER0 = (1u << UART0_RX_IRQ) | (1u << UART0_TX_IRQ);
}

/* Starts transmission when the TX chain is idle; the TX interrupt carries
 * on from there. */
static void tx_kick(void)
{
    irq_disable();
    tx_next();
    irq_enable();
}

static void uart_write(void *ctx, const uint8_t *bytes, size_t n)
{
    (void)ctx;
    for (size_t i = 0; i < n; i++) {
        while (!ring_put(&fw.tx, bytes[i]))
            tx_kick(); /* ring full: wait for the ISR to make room */
    }
    tx_kick();
}

static void systick_init(void)
{
    SYST_RVR = BOARD_SYSCLK_HZ / 1000u - 1u;
    SYST_CVR = 0;
    SYST_CSR = SYST_CSR_ENABLE_TICKINT_CPUCLK;
}

#define WDOG_TIMEOUT_MS 100u /* to the NMI; the reset follows one period later */

static void wdog_init(void)
{
    WDOG_LOCK = WDOG_UNLOCK_KEY;
    WDOG_LOAD = BOARD_SYSCLK_HZ / 1000u * WDOG_TIMEOUT_MS;
    WDOG_CTRL = WDOG_CTRL_INTEN | WDOG_CTRL_RESEN;
    WDOG_LOCK = 0;
}

static void wdog_feed(void)
{
    WDOG_LOCK = WDOG_UNLOCK_KEY;
    WDOG_INTCLR = 1u;
    WDOG_LOCK = 0;
}

/* What a wedged main loop looks like: interrupts off, spinning, the
 * watchdog unfed. Only the DIAG request leads here, and only unarmed. */
static void hang(void)
{
    irq_disable();
    for (;;) {
    }
}

int main(void)
{
    uart_init();
    systick_init();
    wdog_init();

    iso_fb_mcu_config cfg;
    iso_fb_mcu_config_board(&cfg);
    if (iso_fb_mcu_init(&fw.node, &cfg, uart_write, 0, fw.ms) != 0)
        hang();

    uint32_t last = fw.ms;
    for (;;) {
        uint8_t b[32];
        size_t n = 0;
        while (n < sizeof b && ring_get(&fw.rx, &b[n]))
            n++;
        if (n)
            iso_fb_mcu_rx(&fw.node, b, n);
        uint32_t now = fw.ms;
        if (now != last) {
            last = now;
            iso_fb_mcu_tick(&fw.node, now);
        }
        if (fw.node.hang_requested) {
            while (fw.tx.head != fw.tx.tail) /* let the ACK out first */
                tx_kick();
            hang();
        }
        wdog_feed();
        tx_kick();
        /* Sleep until the next interrupt unless input is already waiting;
         * WFI with interrupts masked still wakes, so nothing slips between
         * the check and the sleep. */
        irq_disable();
        if (fw.rx.head == fw.rx.tail && fw.ms == last)
            wait_for_interrupt();
        irq_enable();
    }
}
