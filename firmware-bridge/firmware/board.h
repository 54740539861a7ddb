/* firmware-bridge/firmware/board.h -- the few registers of ARM's MPS2
 * AN385 (Cortex-M3) this firmware touches, as QEMU's mps2-an385 models
 * them: CMSDK APB UART0, CMSDK APB watchdog (its interrupt is the NMI),
 * SysTick and the NVIC. All clocks are the 25 MHz system clock. */
#ifndef FB_BOARD_H
#define FB_BOARD_H

#include <stdint.h>

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

#define BOARD_SYSCLK_HZ 25000000u

/* CMSDK APB UART0; RX interrupt is IRQ 0, TX interrupt IRQ 1. */
#define UART0_BASE 0x40004000u
#define UART_DATA(b) REG32((b) + 0x00u)
#define UART_STATE(b) REG32((b) + 0x04u)
#define UART_CTRL(b) REG32((b) + 0x08u)
#define UART_INTCLR(b) REG32((b) + 0x0Cu)
#define UART_BAUDDIV(b) REG32((b) + 0x10u)
#define UART_STATE_TXFULL 0x1u
#define UART_STATE_RXFULL 0x2u
#define UART_CTRL_TXEN 0x1u
#define UART_CTRL_RXEN 0x2u
#define UART_CTRL_TXINT 0x4u
#define UART_CTRL_RXINT 0x8u
#define UART_INT_TX 0x1u
#define UART_INT_RX 0x2u
#define UART0_RX_IRQ 0u
#define UART0_TX_IRQ 1u

/* CMSDK APB watchdog: counts LOAD down at 25 MHz; the first expiry raises
 * the interrupt (NMI on this board), the second one, with the interrupt
 * still pending and RESEN set, resets the system. INTCLR reloads. */
#define WDOG_BASE 0x40008000u
#define WDOG_LOAD REG32(WDOG_BASE + 0x000u)
#define WDOG_CTRL REG32(WDOG_BASE + 0x008u)
#define WDOG_INTCLR REG32(WDOG_BASE + 0x00Cu)
#define WDOG_LOCK REG32(WDOG_BASE + 0xC00u)
#define WDOG_UNLOCK_KEY 0x1ACCE551u
#define WDOG_CTRL_INTEN 0x1u
#define WDOG_CTRL_RESEN 0x2u

#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define SYST_CSR_ENABLE_TICKINT_CPUCLK 0x7u

#define NVIC_ISER0 REG32(0xE000E100u)

static inline void irq_disable(void)
{
    __asm volatile("cpsid i" ::: "memory");
}
static inline void irq_enable(void)
{
    __asm volatile("cpsie i" ::: "memory");
}
static inline void wait_for_interrupt(void)
{
    __asm volatile("wfi" ::: "memory");
}

#endif
