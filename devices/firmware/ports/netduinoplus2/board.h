/*
 * The netduinoplus2 board: clocks, USART1 (the host link), USART2 (the debug console), the carrier
 * output and the sensing piezo's input, paced block by block.
 *
 * Hardware image: TIM2's update at BOARD_DAC_RATE_HZ triggers both DAC1 (PA4, the amplifier's input) and
 * ADC1 (PA1, the sensing piezo), so the i-th ADC sample measures the plate while the i-th DAC sample
 * plays. DMA1 stream 5 feeds the DAC and DMA2 stream 0 drains the ADC, each over a circular buffer of two
 * blocks, in step. DMA2's half- and full-transfer interrupts call the block function with the half just
 * measured (and just played): it reads that half of the ADC buffer and refills that half of the DAC
 * buffer, which plays after the other half, already filled, now playing.
 *
 * QEMU image: QEMU models neither DAC nor ADC signal nor DMA, and its timers' interrupts come late and
 * irregularly (QEMU 7.2: TIM2..5 re-arm from the time of their last register write; SysTick loses the
 * time it fires late), but their counters read the virtual clock exactly (TIM5: nanoseconds). So SysTick
 * interrupts every millisecond or so, and its handler runs as many blocks as TIM5 says are due (up to
 * BOARD_CATCH_UP at a time): for each, the emulated plate (emulated_plate.h) plays the DAC half that
 * played in that block and writes the ADC half it measured, then the same block function runs. When more
 * than BOARD_STALL_BLOCKS are due, QEMU itself was not running (its host descheduled it): the board was
 * frozen with it, so that time is skipped (counted in board_skipped_ms) rather than played at once while
 * the link, frozen too, still holds the frames of that time: as a real board, which is never
 * descheduled, would have heard them, its watchdog must not fire for the emulator's stall.
 *
 * The link: USART1, by DMA on hardware (the main loop hands what arrived to board_link_received() in bulk
 * and sends what board_link_take() gives a chunk at a time), by the receive interrupt under QEMU (a byte at
 * a time: QEMU models no DMA).
 */
#ifndef UG_BOARD_H
#define UG_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ug_safety.h"

#define BOARD_NAME "netduinoplus2"  /* the boot line's board= and the core's name (ports/common/port.c) */
/* what refreshes the watchdog on both marks (the boot line's watchdog=): QEMU models no IWDG, TIM3 checks them */
#ifdef UG_BOARD_QEMU
#define BOARD_WATCHDOG_NAME "stand-in-timer"
#else
#define BOARD_WATCHDOG_NAME "iwdg"
#endif
#define BOARD_BENCH_PER_COUNT 1u   /* the budget image's clock, TIM5 under -icount shift=0: one instruction a count */
#define BOARD_CLOCK_PER_US 1000u   /* the fault path's clock (board_silent_at): ns (TIM5 under QEMU) */
#define BOARD_CORE_HZ 168000000u   /* the STM32F405 at full speed; QEMU's netduinoplus2 fixes this clock */
#define BOARD_APB1_HZ 42000000u    /* HCLK / 4: USART2 */
#define BOARD_APB2_HZ 84000000u    /* HCLK / 2: USART1 */
#define BOARD_TIMER_APB1_HZ 84000000u  /* APB1 timers run at twice APB1 when it is divided */
#define BOARD_QEMU_TIMER_HZ 1000000000u  /* QEMU 7.2's TIM2..5 count virtual nanoseconds (their default clock) */
#define BOARD_BAUD 921600u         /* the host's default (docs/protocol.md) */
#define BOARD_CONSOLE_BAUD 115200u
#define BOARD_LINK_BYTES_PER_S (BOARD_BAUD / 10u)  /* what USART1 carries (8N1: ten bits a byte), HELLO_REPLY */
/* What QEMU's emulated USART1 carries, stated in HELLO_REPLY so that the host fits its stream to it: QEMU hands
   the firmware one byte per round trip between two of its threads. Measured with bench/bench_qemu_link.py (the
   host offers HEARTBEAT frames at a paced rate for 5 s; the board's own rx_bytes counter, from its statistics
   lines, over the time), at load average 10-12 on the two-core machine: 14 000 B/s offered were taken whole
   (13.8-13.9 kB/s), 28 000-40 000 offered gave at most 14.8-15.1 kB/s taken, and a link overfed (or written as
   fast as the pty takes) fell to 1-10 kB/s, the board's main loop starved by a byte interrupt each. The image
   states the rate it was seen to carry whole; the host's stream takes at most half of it (LINK_MARGIN). */
#define BOARD_QEMU_LINK_BYTES_PER_S 14000u
#define BOARD_TICK_HZ 1000u        /* SysTick */
#define BOARD_DRIVE_RATE_HZ 48000u /* the core's drive samples a second (its sample_rate_hz) */
#define BOARD_OVERSAMPLE 5u        /* DAC (and ADC) samples a drive sample (the core's dac_oversample) */
#define BOARD_DAC_RATE_HZ (BOARD_DRIVE_RATE_HZ * BOARD_OVERSAMPLE)  /* 240 kHz: 9.6 a period at 25 kHz */
#define BOARD_BLOCK_DRIVE 48u      /* drive samples a block: 1 ms, one tick of the core */
#define BOARD_BLOCK_SAMPLES (BOARD_BLOCK_DRIVE * BOARD_OVERSAMPLE)  /* 240 DAC and ADC samples a block */
#define BOARD_CATCH_UP 8u          /* QEMU: blocks run at most in one SysTick interrupt */
#define BOARD_STALL_BLOCKS 20u     /* QEMU: more blocks due than this, and QEMU was stalled: the time is skipped */
#define BOARD_CONSOLE_PRIORITY 0xA0u /* USART2, the debug console: below everything */
#define BOARD_BLOCK_PRIORITY 0x60u /* the block interrupt (the core's tick, DAC and ADC), and BASEPRI's mask */
#define BOARD_LINK_PRIORITY 0x40u  /* USART1: above the blocks, so a byte never waits for one */
#define BOARD_WATCHDOG_PRIORITY 0x00u /* QEMU: SysTick, the clock and the watchdog's stand-in, above everything */
/* The hardware watchdog's timeout: both marks (block interrupt, main loop) must be seen within it. Hardware: the
   IWDG at the LSI's nominal 32 kHz (17-47 kHz: 2.7-7.5 ms); QEMU: the stand-in's, on the virtual clock. */
#define BOARD_WATCHDOG_US 4000u
#define BOARD_WATCHDOG_STALL_US 1500u /* QEMU: a look this late after the last: QEMU stalled, the window restarts */
#define BOARD_WATCHDOG_BOOT_US 200000u /* QEMU: the window while the board warms up (QEMU translating its code) */
#define BOARD_WATCHDOG_WARM_TAKES 300u /* QEMU: ... until both marks were seen this many times */
#define BOARD_HANG_SPAN_BYTES 16u   /* QEMU: a block interrupt found within this of where it was at the last look
                                       has not moved on (a spin loop of a few instructions) */
#define BOARD_WATCHDOG_BUSY_US 50000u /* QEMU: the main loop's mark excused while the block interrupt catches up */
#define BOARD_WATCHDOG_MISSES 3u      /* ... and expires after this many looks in a row without both marks, and
                                         BOARD_WATCHDOG_US of virtual time (one look after QEMU itself stalled
                                         is not the board's fault) */

#include "ug_board.h"

#endif
