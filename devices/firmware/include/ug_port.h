/*
 * ug_port.h - the port interface between ultraglide's portable firmware core and a board.
 *
 * The core (devices/firmware/core/) never touches hardware. A board port (ports/<board>/) owns the
 * UART, a 1 kHz timer, the DAC or PWM that plays the carrier and the ADC that reads the sensing
 * piezo and force sensors, and joins them to the core through the calls below. The protocol the
 * core speaks is docs/protocol.md (version 3, and 2 for old hosts); docs/firmware.md describes the
 * architecture and how to port it.
 *
 * Calls INTO the core (declared in ug_core.h), and the context each may be called from:
 *
 *   ug_core_init()          once, before any interrupt that calls the core is enabled.
 *   ug_core_uart_rx()       UART receive interrupt (or DMA idle-line handler): bytes as they come.
 *                           Bounded: copies into the core's receive ring, nothing else.
 *   ug_core_uart_tx()       UART transmit interrupt or DMA completion, or the main loop: takes up to
 *                           max bytes the core has queued for the host.
 *   ug_core_tick()          a timer interrupt every UG_TICK_US microseconds (1 ms). Runs the watchdog,
 *                           fault timers and telemetry/SENSORS scheduling. Bounded, no allocation.
 *   ug_core_dac_block()     the DAC/PWM DMA half- or full-transfer interrupt: fills the next block of
 *                           carrier samples (int16, full-scale drive = +-32767). Bounded by the block.
 *   ug_core_drive_block()   instead of ug_core_dac_block() on a board (or the simulator) that makes
 *                           the carrier itself: the drive envelope, fraction of full scale.
 *   ug_core_adc_block()     the ADC DMA interrupt: measured vibration amplitude (um peak-to-peak) and
 *                           forces (N) for the samples most recently produced, one per drive sample.
 *   ug_core_set_stage_hot() wherever the board measures its driver stage's temperature.
 *   ug_core_poll()          the main loop, as often as it can: decodes and handles host frames,
 *                           sends telemetry and SENSORS frames. Takes critical sections (below).
 *   ug_core_block()         the block interrupt, once a block, instead of the three block calls above:
 *                           ADC, DAC and tick advanced together, in that order (ug_core.h).
 *   ug_core_lost_time()     the block interrupt, when it came late (both halves had played): the blocks
 *                           it could not run, in ms; the port has silenced the DAC, nothing stale plays.
 *
 * A port's duties, beyond implementing the calls out below:
 *   - at boot, before ug_core_init: the output silent (ug_port_output_safe(UG_SAFE_POWER_UP)); in
 *     ug_config, what its link carries (link_bytes_per_s, 0 if it cannot say) and why it last started
 *     (reset_stated = 1, reset_reason UG_RESTART_*, reset_detail), so the next HELLO tells the host;
 *   - when ug_core_adc_block / ug_core_block returns less than n, the output went off at that sample:
 *     the half playing now is silenced too (ug_port_output_safe has been called; the port's own DAC
 *     blank of that half follows the return);
 *   - a late block (both DMA halves flagged), a DMA error or a DAC underrun is counted and never
 *     replayed: the DAC is silenced and ug_core_lost_time told;
 *   - a hardware watchdog refreshed only when both the block interrupt and the main loop have run since
 *     the last refresh (ports/common/ug_safety.h's marks); its expiry, and every fault handler, silences
 *     the output by the stronger form below before anything else, then resets;
 *   - the stack guarded (below .bss, or an MPU region) so an overflow faults instead of corrupting the
 *     core's state.
 *
 * The tick, DAC and ADC interrupts (and ug_core_set_stage_hot if called from an interrupt) MUST
 * share one priority, so that none of them preempts another inside the core; the UART receive
 * interrupt may have any priority (it only writes the receive ring). Drive and ADC blocks are
 * sample-aligned: the i-th sample of an ADC block measures the plate while the i-th sample of
 * the drive block produced UG_SENSE_DELAY samples earlier was playing (config.sense_delay_samples).
 *
 * Calls OUT of the core, which a port implements (the context pointer is the one given to
 * ug_core_init):
 */
#ifndef UG_PORT_H
#define UG_PORT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Microseconds between two ug_core_tick() calls. */
#define UG_TICK_US 1000u

/*
 * Enter and leave a critical section: mask the interrupts that call into the core (tick, DAC, ADC)
 * on this CPU, and no other (the link's receive interrupt stays on: it only writes the receive ring).
 * Called from ug_core_poll(), ug_core_next_event(), ug_core_set_stage_hot() and a port's own status
 * reads. Inside, the core copies state and decides; it encodes and copies nothing long there: a
 * SETPOINTS frame's values are copied into the buffer's free room before its section (which commits
 * them), replies are encoded after it, TELEMETRY's payload is a copy, SENSORS' two rings are swapped
 * (the 969-byte frame is encoded with the blocks running). MUST nest (save and restore the previous
 * mask, e.g. BASEPRI on Cortex-M).
 *
 * Measured bound (the longest section, instructions, QEMU -icount shift=0 on the netduinoplus2 budget
 * image, `python bench/bench_firmware.py`): 344 while streaming 48 000 setpoints/s in 240- or 48-value
 * frames with telemetry and SENSORS; 373 for ENABLE 0, whose section includes ug_port_output_safe (the
 * netduinoplus2 port writes both DAC halves, 480 samples, in 120 double-word stores). Before: 4 388 while
 * streaming (a full SENSORS frame encoded inside: ~15-20 k). At 168 MHz and 2 cycles an instruction, 373
 * instructions are 4.4 us.
 */
void ug_port_critical_enter(void *port);
void ug_port_critical_exit(void *port);

/*
 * The core queued bytes for the host (a frame ended in its transmit ring): start the UART's
 * transmission if it is idle. Called from ug_core_poll() (main loop). May do nothing on a port that
 * drains ug_core_uart_tx() from its main loop anyway.
 */
void ug_port_tx_ready(void *port);

/*
 * Simulator only (config.sim_faults = 1): the host asked for an injected transport fault, kind 1 drop,
 * 2 corrupt, 3 hang, 4 disconnect, for duration_ms. Called from ug_core_poll() after the SIM_FAULT's
 * ACK was queued. A board port (sim_faults = 0, SIM_FAULT answered NAK 4) never sees it and may leave
 * it empty.
 */
void ug_port_sim_fault(void *port, uint8_t kind, uint16_t duration_ms);

/*
 * The output must be silent now: no drive reaches the plate from the next output sample on. `why` is one of
 * UG_SAFE_*. The core calls it whenever the output goes off (a host's DISABLE, a trip, an overheat, a HELLO
 * that disabled, the end of the protocol watchdog's ramp), from the block interrupt or from ug_core_poll()
 * inside a critical section; it MUST NOT block and MUST take effect without waiting for the next block: on a
 * DAC fed by DMA from two halves, both halves to mid-scale (what the DMA plays next is silence) and, where the
 * board has one, the amplifier's enable pin low. The output comes back only through the blocks the core fills
 * after a new ENABLE. A port calls the same routine itself at power-up (before the carrier's clock starts),
 * and its fault handlers and hardware watchdog call the stronger form, which does not rely on the DMA: stop
 * the DMA and the converter's trigger and load mid-scale by software (a DAC that converts only on a timer's
 * trigger holds its last sample when that timer stops) - in assembly, before any C that uses the stack.
 */
enum {
    UG_SAFE_POWER_UP = 0, /* the port, before its output starts */
    UG_SAFE_DISABLE = 1,  /* the core: the output went off (DISABLE, trip, overheat, HELLO) */
    UG_SAFE_RAMP_END = 2, /* the core: the protocol watchdog's ramp reached zero */
    UG_SAFE_WATCHDOG = 3, /* the port: its hardware watchdog (or its stand-in) expired */
    UG_SAFE_FAULT = 4     /* the port: a fault handler */
};
void ug_port_output_safe(void *port, uint8_t why);

/*
 * Drive samples the ADC has taken since the last block the port handed to the core (ug_core_adc_block or
 * ug_core_block): where its DMA is within the half it fills now; 0 where the board cannot tell. Called from
 * ug_core_poll() inside a critical section when a CLOCK request is answered (its CLOCK_REPLY states the sensor
 * clock: the core's samples so far and these). MUST NOT be more than the ADC has taken (the reply's clock is never
 * ahead of the device's); a port that returns 0 makes it up to a block behind, and its block MUST then be at most
 * UG_MAX_CLOCK_LAG_MS long (the reference boards' blocks are 1 ms). A block that fell due and has not been handed
 * over (its interrupt masked or late) leaves the core a block behind the ADC whatever this says (at most a block
 * less one: never more than one block's worth); the reference boards read their DMA or block clock, and their QEMU
 * images run a block that fell due before the core's poll (ports/common/ug_board.h).
 */
uint32_t ug_port_samples_since_block(void *port);

#ifdef __cplusplus
}
#endif

#endif /* UG_PORT_H */
