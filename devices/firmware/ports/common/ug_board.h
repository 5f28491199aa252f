/*
 * ug_board.h - what a board gives the shared glue (ports/common/port.c, main.c): the link's bytes, the debug
 * console, the DAC and ADC halves of each block, the block clock, the masks, the safe stops, the watchdog's
 * marks and the reset record, and (QEMU images) the emulated plate and the injected faults. Each port's board.h
 * defines its constants (BOARD_NAME, BOARD_WATCHDOG_NAME, rates, block sizes, priorities) and includes this;
 * its board.c implements it. Comments name the netduinoplus2's peripherals where they differ.
 */
#ifndef UG_BOARD_API_H
#define UG_BOARD_API_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ug_safety.h"

/* Run for each block (in the block interrupt): `half` (0 or 1) names the halves of the ADC buffer just
   measured and of the DAC buffer to refill. */
typedef void (*board_block_fn)(uint32_t half);
/* Run instead when `blocks` blocks' time was lost (a late block interrupt: both halves silenced, none refilled). */
typedef void (*board_lost_fn)(uint32_t blocks);

void board_init(void);
/* Milliseconds since boot (the board's block clock). */
uint32_t board_millis(void);

/* The port's side of the link (port.c): bytes arrived (hardware: from the main loop; QEMU: from USART1's
   interrupt, one at a time; n = 0 only wakes the main loop); up to max bytes to send (main loop). */
void board_link_received(const uint8_t *bytes, size_t n);
size_t board_link_take(uint8_t *out, size_t max);
/* Main loop: hand over the bytes received and start sending what the core queued. */
void board_link_service(void);
/* Bytes the USART itself lost (a byte arrived before the previous one was read). */
uint32_t board_link_overruns(void);

/* A line for the debug console (USART2), dropped whole when its ring is full. */
void board_console_write(const char *text);

/* The two halves of the DAC buffer (left-aligned words for DHR12L1: mid-scale 0x8000 = no drive) and of the
   ADC buffer (12-bit codes). */
uint16_t *board_dac_half(uint32_t half);
const uint16_t *board_adc_half(uint32_t half);
/* No drive at once: the DAC half `half` to mid-scale (the half playing now, on a trip or a disable). */
void board_dac_blank(uint32_t half);

/* Start the carrier's block clock: `block` runs for each block from then on. */
void board_carrier_start(board_block_fn block, board_lost_fn lost);
/* Drive samples taken since the block last given to `block` (ug_port_samples_since_block: the CLOCK reply's place
   within the block), read from the peripheral that clocks the samples (hardware: DMA2 stream 0's count of ADC
   conversions left; QEMU: the board's free-running clock against when the next block falls due), in
   [0, BOARD_BLOCK_DRIVE): never ahead of the samples taken; 0 before the carrier starts. With the blocks masked. */
uint32_t board_samples_since_block(void);
#ifdef UG_BOARD_QEMU
/* The raw reading behind the last board_samples_since_block (the console's `ev clock_read`, by which a test checks
   the CLOCK reply against the board's own clock): the reads so far, the board clock's count then (netduinoplus2:
   TIM5's virtual ns; mps2-an386: TIMER1's PCLK cycles), its count when the next block falls due, the blocks run. */
typedef struct {
    uint32_t reads, ticks, due, blocks;
} board_clock_read_t;
void board_last_clock_read(board_clock_read_t *out);
/* Main loop, before the core's poll: a block the board's clock says is due and QEMU's timer has not yet run (its
   timers fire late on a loaded host) is run now (the block interrupt pended), as a board's DMA interrupt would
   have; so the core answers a CLOCK with that block its own. */
void board_run_due_blocks(void);
#endif

/* Mask and unmask the block interrupt (BASEPRI), leaving the link's interrupt on; nests when the caller
   keeps what mask returns and gives it back to unmask. */
uint32_t board_mask_blocks(void);
void board_unmask_blocks(uint32_t previous);

#ifdef UG_BOARD_QEMU
/* The emulated plate's truth and its sensing scale (um p-p per ADC code); before board_carrier_start. */
void board_emulate_plate(float resonance_hz, float q, float drift_hz_per_s, float full_scale_um_pp,
                         float um_pp_per_code);
/* Its own peak-to-peak so far (um), and the milliseconds skipped while QEMU was stalled. */
float board_plate_peak_um_pp(void);
uint32_t board_skipped_ms(void);
/* The emulated plate plays DAC half `half` and writes the ADC half it measured (what SysTick does before
   each block; the budget image calls it itself). */
void board_emulate_block(uint32_t half);
#endif

/* Safe state: DAC to mid-scale (no drive), its timers and DMA stopped, interrupts off, wait. */
void board_fault_stop(void);

/* The output silent at once, the DMA left running (ug_port_output_safe): both DAC halves to mid-scale, so
   what the DMA plays next is silence. */
void board_output_safe(void);
/* The output silent without the DMA (fault handlers, the watchdog): the DAC's DMA and trigger stopped and
   mid-scale loaded by software. Uses no stack beyond its own frame; the fault handlers do the same in
   assembly (startup.c) before any C. */
void board_output_off(void);
/* Note why and reset the board now (SYSRESETREQ); the output is made silent first. Never returns. */
void board_reset(uint32_t reason, uint32_t detail) __attribute__((noreturn));
/* The fault handlers' C part (after their assembly made the output silent and reset the stack). */
void board_fault_reset(void) __attribute__((noreturn));

/* The block interrupt's and the main loop's marks, and the hardware watchdog they feed (hardware: the IWDG
   refreshed in the block interrupt when both were set; QEMU: TIM3's stand-in checks them). */
void board_watchdog_start(void);
void board_watchdog_service(void);
/* QEMU: how many times the stand-in has looked at the marks. */
uint32_t board_watchdog_looks(void);
/* QEMU: looks that came late (QEMU itself stalled) and restarted the window. */
uint32_t board_watchdog_stalls(void);
/* Why the board last restarted (UG_RESET_*) and the record of it (ug_safety.h); read once at boot. */
uint32_t board_reset_reason(void);
const struct ug_reset_record *board_reset_record(void);
/* Blocks that came late (both DMA halves flagged, or QEMU's catch-up), DMA transfer errors, DAC underruns. */
uint32_t board_late_blocks(void);
uint32_t board_dma_errors(void);
uint32_t board_dac_underruns(void);
/* The board's clock for fault timing: microseconds (QEMU: TIM5's virtual nanoseconds / 1000). */
uint32_t board_time_us(void);
#ifdef UG_BOARD_BENCH
/* The budget image's clock (bench.c): under -icount shift=0, BOARD_BENCH_PER_COUNT instructions a count (board.h). */
uint32_t board_bench_clock(void);
/* Before the budget image measures: every interrupt that would be counted into its figures off, its clock running. */
void board_bench_start(void);
#endif

#ifdef UG_BOARD_QEMU
/* The fault the console asked for (ug_safety.h UG_INJECT_*), 0 for none; the main loop and the block
   interrupt act on it. */
uint32_t board_injected_fault(void);
/* Note the injection's time and make it happen in this context (hangs, overflows or faults: never returns). */
void board_inject_now(uint32_t kind) __attribute__((noreturn));
#endif

/* Sleep until the next interrupt. */
void board_wait_for_interrupt(void);

#endif
