/*
 * The registers of the mps2-an386 (ARM MPS2 board, AN386 FPGA image: a Cortex-M4F with CMSDK APB peripherals)
 * that this port uses, from the AN386 application note's memory map and the Cortex-M System Design Kit's
 * peripheral descriptions (APB UART, APB timer, APB watchdog), and the ARMv7-M system control space. Written
 * for ultraglide.
 */
#ifndef UG_CMSDK_H
#define UG_CMSDK_H

#include <stdint.h>

#define REG32(address) (*(volatile uint32_t *)(uintptr_t)(address))
#define REG8(address) (*(volatile uint8_t *)(uintptr_t)(address))

/* ---- CMSDK APB UART: UART0 0x40004000 (the host link), UART1 0x40005000 (the debug console) --------------- */
#define UART0_BASE 0x40004000u
#define UART1_BASE 0x40005000u
#define UART_DATA(base) REG32((base) + 0x00u)
#define UART_STATE(base) REG32((base) + 0x04u)     /* bit 0 TX full, 1 RX full, 2 TX overrun, 3 RX overrun */
#define UART_CTRL(base) REG32((base) + 0x08u)      /* bit 0 TX on, 1 RX on, 2 TX int, 3 RX int, 5 RX overrun int */
#define UART_INTSTATUS(base) REG32((base) + 0x0Cu) /* read: bit 0 TX, 1 RX, 2 TX overrun, 3 RX overrun; write 1 clears */
#define UART_BAUDDIV(base) REG32((base) + 0x10u)   /* PCLK / baud, at least 16 */
#define UART_STATE_TXFULL (1u << 0)
#define UART_STATE_RXFULL (1u << 1)
#define UART_STATE_RXOVR (1u << 3)
#define UART_CTRL_TXEN (1u << 0)
#define UART_CTRL_RXEN (1u << 1)
#define UART_CTRL_RXIE (1u << 3)
#define UART_INT_RX (1u << 1)
#define UART0_RX_IRQn 0u  /* each UART's RX interrupt; its TX interrupt is the next */
#define UART1_RX_IRQn 2u

/* ---- CMSDK APB timers: TIMER0 0x40000000 (IRQ 8), TIMER1 0x40001000 (IRQ 9); count down at PCLK ----------- */
#define TIMER0_BASE 0x40000000u
#define TIMER1_BASE 0x40001000u
#define TIMER_CTRL(base) REG32((base) + 0x00u)     /* bit 0 enable, 3 interrupt enable */
#define TIMER_VALUE(base) REG32((base) + 0x04u)
#define TIMER_RELOAD(base) REG32((base) + 0x08u)
#define TIMER_INTCLEAR(base) REG32((base) + 0x0Cu)
#define TIMER_CTRL_EN (1u << 0)
#define TIMER_CTRL_IRQEN (1u << 3)
#define TIMER0_IRQn 8u
#define TIMER1_VALUE_ADDRESS 0x40001004u  /* the fault handlers' assembly reads the clock here */

/* ---- CMSDK APB watchdog (0x40008000): its interrupt is the NMI on the MPS2 boards; a second expiry with the
   interrupt still set resets the system when RESEN is set. Writes need WDOGLOCK unlocked (0x1ACCE551). ------ */
#define WDOG_BASE 0x40008000u
#define WDOG_LOAD REG32(WDOG_BASE + 0x000u)     /* writing it reloads the counter */
#define WDOG_VALUE REG32(WDOG_BASE + 0x004u)
#define WDOG_CONTROL REG32(WDOG_BASE + 0x008u)  /* bit 0 INTEN (counts, interrupts), 1 RESEN */
#define WDOG_INTCLR REG32(WDOG_BASE + 0x00Cu)   /* any write: the interrupt cleared, the counter reloaded */
#define WDOG_RIS REG32(WDOG_BASE + 0x010u)
#define WDOG_LOCK REG32(WDOG_BASE + 0xC00u)
#define WDOG_CONTROL_INTEN (1u << 0)
#define WDOG_CONTROL_RESEN (1u << 1)
#define WDOG_UNLOCK_KEY 0x1ACCE551u

/* ---- ARMv7-M system control space ----------------------------------------------------------------------- */
#define NVIC_ISER(n) REG32(0xE000E100u + 4u * (n))
#define NVIC_ISPR(n) REG32(0xE000E200u + 4u * (n))
#define NVIC_IABR(n) REG32(0xE000E300u + 4u * (n))
#define NVIC_IPR_BYTE(irq) REG8(0xE000E400u + (irq))
#define SCB_VTOR REG32(0xE000ED08u)
#define SCB_AIRCR REG32(0xE000ED0Cu)
#define SCB_SHPR3 REG32(0xE000ED20u)
#define SCB_SHCSR REG32(0xE000ED24u)
#define SCB_CFSR REG32(0xE000ED28u)
#define SCB_CPACR REG32(0xE000ED88u)
#define SCB_AIRCR_VECTKEY (0x05FAu << 16)
#define SCB_AIRCR_SYSRESETREQ (1u << 2)
#define MPU_CTRL REG32(0xE000ED94u)
#define MPU_RNR REG32(0xE000ED98u)
#define MPU_RBAR REG32(0xE000ED9Cu)
#define MPU_RASR REG32(0xE000EDA0u)
#define MPU_CTRL_ENABLE (1u << 0)
#define MPU_CTRL_PRIVDEFENA (1u << 2)  /* the default map for everything no region covers */
#define MPU_RASR_ENABLE (1u << 0)
#define MPU_RASR_XN (1u << 28)
#define MPU_RASR_SIZE(log2_bytes) (((log2_bytes) - 1u) << 1)  /* AP = 0: no access at all */

#endif
