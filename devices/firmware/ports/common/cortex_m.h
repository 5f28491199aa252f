/*
 * cortex_m.h - what every Cortex-M board port does the same way (ports/common/): start-up (the C run-time set up
 * and main called), the reset path (the output silenced, the reset record written, SYSRESETREQ) and the restart
 * reason read at boot. The architectural registers only (ARMv7-M's system control space); the board's own stay in
 * its port.
 *
 * The board gives: board_output_off() (ug_board.h), BOARD_CLOCK_PER_US in its board.h (its clock's units a
 * microsecond: board_silent_at and the injection's stamp are in them), and defines nothing of what is here.
 */
#ifndef UG_CORTEX_M_H
#define UG_CORTEX_M_H

#include <stdint.h>

/* Set by the fault handlers' assembly (startup.c) before any C, and by board_output_off: the emulated or real DAC
   stopped, and the board's clock when it was. */
extern volatile uint32_t board_dac_stopped;
extern volatile uint32_t board_silent_at;

/* The reset handler's work after it set the stack pointer: .data copied, .bss zeroed, the FPU enabled, the vector
   table at `vectors`, main called (it never returns; should it, the processor sleeps). */
__attribute__((noreturn)) void cortex_m_start(const void *vectors);

/* At boot: why the board last started, from its reset record, else (from_ram) its RAM's mark (ug_safety.h); the
   reason board_reset_reason() states. */
uint32_t cortex_m_reset_read(int from_ram);
/* The board's hardware said more than the record (RCC_CSR): the reason stated instead. */
void cortex_m_reset_reason_set(uint32_t reason);

#endif
