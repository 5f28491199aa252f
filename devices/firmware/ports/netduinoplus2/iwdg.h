/*
 * The STM32F405's independent watchdog (IWDG, RM0090 §19): the hardware image's watchdog, clocked by the
 * 32 kHz LSI (17-47 kHz over parts and temperature), which no software can stop once started.
 *
 * Start: KR 0x5555 (unlock PR and RLR), PR, RLR, wait until SR shows both written (PVU, RVU clear; bounded),
 * KR 0xCCCC (start: from then on the counter runs), KR 0xAAAA (reload the counter from RLR). Refresh: KR 0xAAAA.
 * QEMU's netduinoplus2 does not model the IWDG (nor its LSI): the QEMU image stands in with a timer of higher
 * priority checking the same two marks (board.c) and says so on its boot line (watchdog=stand-in-timer).
 *
 * Register access goes through UG_IWDG_WRITE/READ so the host's tests compile this file against a recording
 * register file (-DUG_HOST_REGISTERS; tests/test_firmware_watchdog.py) and check the sequence itself.
 */
#ifndef UG_IWDG_H
#define UG_IWDG_H

#include <stdint.h>

#define IWDG_BASE 0x40003000u
#define IWDG_KR_OFFSET 0x00u
#define IWDG_PR_OFFSET 0x04u
#define IWDG_RLR_OFFSET 0x08u
#define IWDG_SR_OFFSET 0x0Cu
#define IWDG_KEY_UNLOCK 0x5555u
#define IWDG_KEY_START 0xCCCCu
#define IWDG_KEY_REFRESH 0xAAAAu
#define IWDG_SR_PVU (1u << 0)
#define IWDG_SR_RVU (1u << 1)
#define IWDG_LSI_HZ 32000u /* nominal */
#define IWDG_SR_WAIT 100000u /* reads of SR at most before starting anyway (PVU/RVU take 5 LSI periods) */

#ifdef UG_HOST_REGISTERS
void ug_host_register_write(uint32_t address, uint32_t value);
uint32_t ug_host_register_read(uint32_t address);
#define UG_IWDG_WRITE(offset, value) ug_host_register_write(IWDG_BASE + (offset), (value))
#define UG_IWDG_READ(offset) ug_host_register_read(IWDG_BASE + (offset))
#else
#define UG_IWDG_WRITE(offset, value) (*(volatile uint32_t *)(IWDG_BASE + (offset)) = (value))
#define UG_IWDG_READ(offset) (*(volatile uint32_t *)(IWDG_BASE + (offset)))
#endif

/* The prescaler code (PR, 0 = /4 .. 6 = /256) and reload (RLR, 1..4095) for a timeout of timeout_us at
   lsi_hz: the smallest prescaler that fits, the reload rounded down (never longer than asked). */
void ug_iwdg_divider(uint32_t timeout_us, uint32_t lsi_hz, uint32_t *pr, uint32_t *rlr);
/* Start the watchdog with that timeout (the register sequence above); returns the reload written. */
uint32_t ug_iwdg_start(uint32_t timeout_us, uint32_t lsi_hz);
/* Reload its counter (KR 0xAAAA). */
void ug_iwdg_refresh(void);

#endif
