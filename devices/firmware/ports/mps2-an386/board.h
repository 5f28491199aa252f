/*
 * The mps2-an386 board (ARM's MPS2 with the AN386 FPGA image: a Cortex-M4F at 25 MHz and the Cortex-M System
 * Design Kit's APB peripherals), as QEMU models it: UART0 the host link, UART1 the debug console, TIMER0 the
 * block clock, TIMER1 a free-running count of PCLK cycles (the board's clock), and the CMSDK watchdog, whose
 * interrupt is the NMI.
 *
 * The board has no DAC or ADC that QEMU models: as the netduinoplus2's QEMU image, each block the emulated plate
 * (ports/common/emulated_plate.h) plays the DAC half that played and writes the ADC half it measured, then the
 * shared block function runs (ports/common/port.c). TIMER0 interrupts every millisecond (QEMU's CMSDK timers
 * re-arm periodically) and its handler runs as many blocks as TIMER1 says are due, skipping a stall of QEMU
 * itself as the netduinoplus2's image does.
 *
 * The watchdog: the block interrupt refreshes the CMSDK watchdog only when both marks (block interrupt, main
 * loop) were set since the last refresh (ports/common/ug_safety.h). Its first expiry raises the NMI, whose
 * handler silences the output, writes the reset record and resets the board (SYSRESETREQ); a second expiry
 * would reset it in hardware (RESEN, BOARD_WATCHDOG_RESEN below: off under QEMU) should the handler not run.
 */
#ifndef UG_BOARD_H
#define UG_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define BOARD_NAME "mps2-an386"    /* the boot line's board= and the core's name (ports/common/port.c) */
#define BOARD_WATCHDOG_NAME "cmsdk" /* the CMSDK APB watchdog, its first expiry an NMI */
#define BOARD_CORE_HZ 25000000u    /* the AN386's system clock, PCLK too (QEMU's SYSCLK_FRQ) */
#define BOARD_TICKS_PER_US (BOARD_CORE_HZ / 1000000u)
#define BOARD_BENCH_PER_COUNT (1000000000u / BOARD_CORE_HZ) /* the budget image's clock, TIMER1's PCLK under -icount
                                                        shift=0 (1 ns an instruction): 40 instructions a count */
#define BOARD_CLOCK_PER_US BOARD_TICKS_PER_US /* the fault path's clock (board_silent_at): TIMER1's ticks */
#define BOARD_BAUD 921600u         /* the host's default (docs/protocol.md) */
#define BOARD_CONSOLE_BAUD 115200u
#define BOARD_LINK_BYTES_PER_S (BOARD_BAUD / 10u)  /* what UART0 carries (8N1: ten bits a byte), HELLO_REPLY */
/* What QEMU's emulated UART0 carries, stated in HELLO_REPLY (measured as the netduinoplus2's board.h tells:
   `bench/bench_qemu_link.py --board mps2-an386 --offer N --runs 1 --seconds 4` at load average 3.4: 14 000 B/s
   offered were taken whole (13 999), 28 000 offered starved the main loop to 4 261 taken). QEMU hands the CMSDK
   UART a byte per round trip as it does USART1. */
#define BOARD_QEMU_LINK_BYTES_PER_S 14000u
#define BOARD_DRIVE_RATE_HZ 48000u /* the core's drive samples a second (its sample_rate_hz) */
#define BOARD_OVERSAMPLE 5u        /* DAC (and ADC) samples a drive sample (the core's dac_oversample) */
#define BOARD_DAC_RATE_HZ (BOARD_DRIVE_RATE_HZ * BOARD_OVERSAMPLE)  /* 240 kHz, as the netduinoplus2's */
#define BOARD_BLOCK_DRIVE 48u      /* drive samples a block: 1 ms, one tick of the core */
#define BOARD_BLOCK_SAMPLES (BOARD_BLOCK_DRIVE * BOARD_OVERSAMPLE)
#define BOARD_CATCH_UP 8u          /* blocks run at most in one block interrupt */
#define BOARD_STALL_BLOCKS 20u     /* more blocks due than this: QEMU was stalled, the time is skipped */
#define BOARD_CONSOLE_PRIORITY 0xA0u /* UART1, the debug console: below everything */
#define BOARD_BLOCK_PRIORITY 0x60u /* TIMER0, the block interrupt, and BASEPRI's mask */
#define BOARD_LINK_PRIORITY 0x40u  /* UART0: above the blocks, so a byte never waits for one */
/* The CMSDK watchdog's timeout: both marks must be seen within it (its first expiry, the NMI, stops the board). */
#define BOARD_WATCHDOG_US 3000u  /* 75 000 PCLK cycles: a fault silent within 3 ms of the last refresh, <= 4 ms of it */
#define BOARD_WATCHDOG_BOOT_US 200000u /* the first window, until both marks were seen this many times: */
#define BOARD_WATCHDOG_WARM_REFRESHES 100u /* QEMU translates each code path the first time it runs: the first blocks,
                                              statistics and frames are slow */
#define BOARD_WATCHDOG_STALL_US 2500u /* an NMI this much later than the timeout: QEMU's clock jumped (its host
                                         descheduled it while the board slept), not the board; the window restarts,
                                         counted */
/* The watchdog's second expiry (RESEN) resets the board in hardware should the NMI's handler never run. Left off
   under QEMU: should its clock jump by more than two windows (QEMU on the host's clock, descheduled; or the board
   sleeping under the instruction counter, whose clock then keeps real time, through a stall of its host) both
   expiries pass at once and the board would reset with no record ("power-on"; on the host's clock, three of six 3 s
   boots at load 12 reset so). The QEMU image sleeps (board.c, board_wait_for_interrupt), so its clock does jump: the
   NMI's handler excuses the jump and restarts the counter, which the second expiry stopped (watchdog_rearm). A
   hardware image sets it to 1. */
#ifndef BOARD_WATCHDOG_RESEN
#define BOARD_WATCHDOG_RESEN 0
#endif
#define BOARD_WATCHDOG_EXCUSES 3u   /* NMIs excused as QEMU's stalls in a row without both marks, at most */
#define BOARD_BLOCK_SLOW_US 1500u   /* a block interrupt started this recently at the NMI is QEMU's slowness */
#define BOARD_WATCHDOG_BUSY_US 50000u /* the main loop's mark excused while the block interrupt catches up */

#include "ug_board.h"

#endif
