/*
 * ug_safety.h - what every board port does to fail safe on its own, board-independent (ports/common/).
 *
 * - Two marks for the hardware watchdog: the block interrupt sets one, the main loop the other; the watchdog is
 *   refreshed only when both were set since the last refresh (ug_marks_take), so a hung block interrupt, a main
 *   loop stuck (in a critical section or anywhere) or a fault handler that never returns all let it expire.
 * - The reset record: a few words in RAM that no start-up code clears (.noinit), written just before the board
 *   resets itself (watchdog expiry, fault) and read once at the next boot, so the board can say why it
 *   restarted; anything else reads as a power-on (its check word does not match).
 * - Injected faults (the QEMU images' debug console only): the kinds and their names.
 *
 * Contexts: ug_marks_block from the block interrupt, ug_marks_main from the main loop, ug_marks_take from the
 * context that refreshes the watchdog. The marks are C11 atomics (release on set, acquire-exchange on take).
 */
#ifndef UG_SAFETY_H
#define UG_SAFETY_H

#include <stdbool.h>
#include <stdint.h>

/* why the board restarted (the boot line's reset_reason) */
enum {
    UG_RESET_POWER_ON = 0, /* no record: power applied (or a record that did not survive) */
    UG_RESET_WATCHDOG = 1, /* the hardware watchdog (or its stand-in) expired: a mark was missing */
    UG_RESET_FAULT = 2,    /* a fault handler (hard fault, bus/usage/memory fault, stack overflow) */
    UG_RESET_SOFTWARE = 3, /* the firmware asked for a reset for another reason */
    UG_RESET_PIN = 4,      /* the reset pin (hardware: RCC_CSR says so) */
    UG_RESET_REASONS = 5
};
/* (the same codes go on the wire as HELLO_REPLY's restart_reason, ug_protocol.h's UG_RESTART_*: each port that
   states them checks so where it includes both) */

/* an injected fault (the QEMU image's console command `fault KIND`) */
enum {
    UG_INJECT_NONE = 0,
    UG_INJECT_ISR_HANG = 1,        /* the block interrupt stops: it spins for ever */
    UG_INJECT_MAIN_HANG = 2,       /* the main loop stops: it spins for ever, interrupts on */
    UG_INJECT_STACK_OVERFLOW = 3,  /* the main loop recurses until the stack runs off its bottom */
    UG_INJECT_HARD_FAULT = 4,      /* the main loop reads an address nothing answers */
    UG_INJECT_KINDS = 5
};

typedef struct ug_reset_record {
    uint32_t magic;
    uint32_t reason;        /* UG_RESET_* */
    uint32_t detail;        /* a fault's status (Cortex-M: CFSR), else 0 */
    uint32_t injected;      /* the injected fault that led here (UG_INJECT_*), else 0 */
    uint32_t fault_at;      /* the board's clock (its own unit) when it was injected */
    uint32_t silent_after_us; /* from the injection to the output made silent, us (0xFFFFFFFF: not injected) */
    uint32_t where;         /* the program counter the watchdog found running at its expiry (0: none) */
    uint32_t check;         /* ~(magic ^ reason ^ detail ^ injected ^ silent_after_us) */
} ug_reset_record_t;

#define UG_RESET_MAGIC 0x55475253u /* "UGRS" */
#define UG_NOT_INJECTED 0xFFFFFFFFu

/* The record itself (in .noinit; the port's linker script places the section where start-up leaves it). */
extern ug_reset_record_t ug_reset_record;

/* Power kept through the reset: a mark in .noinit, set at every boot, that the next boot finds intact only when
   the RAM kept its contents, i.e. power was never removed. For a board with no reset-cause register (or an
   emulator that models none): a start with no reset record whose mark is intact was a reset from outside the
   firmware with power kept (a reset button, a debugger's SYSRESETREQ, a watchdog's own reset); one whose mark is
   not intact a power-on (a power-on leaves RAM zero under QEMU, random on hardware: the mark and its complement
   matching by chance is 1 in 2^64). Called once a boot, after ug_reset_take; it re-arms the mark. */
bool ug_reset_power_kept(void);
extern uint32_t ug_power_mark[2]; /* the mark and its complement (.noinit) */
/* restart_detail's bit for a power-on or a pin reset told by ug_reset_power_kept: no register said so, the RAM did */
#define UG_RESET_DETAIL_FROM_RAM 1u
/* At boot, for a board that reads no reset-cause register: ug_reset_take's reason when a record was left, else
   UG_RESET_PIN (power kept) or UG_RESET_POWER_ON, with out->detail UG_RESET_DETAIL_FROM_RAM: what the RAM told. */
uint32_t ug_reset_take_from_ram(ug_reset_record_t *out);

/* Note why the board is about to reset (the fault path: no stack beyond a few words, no wait). */
void ug_reset_note(uint32_t reason, uint32_t detail, uint32_t silent_after_us);
/* Note an injected fault about to happen, at the board's clock `at`. */
void ug_reset_note_injection(uint32_t kind, uint32_t at);
/* At boot: the record left before the reset (a power-on when there is none) into *out; clears it. */
uint32_t ug_reset_take(ug_reset_record_t *out);
const char *ug_reset_name(uint32_t reason);

void ug_marks_block(void);
void ug_marks_main(void);
/* The marks set now: 1 the block interrupt's, 2 the main loop's. */
uint32_t ug_marks_peek(void);
/* True, and both marks cleared, when both were set since the last true; false otherwise. */
bool ug_marks_take(void);

/* The kind named by a console line `fault NAME` (isr-hang, main-hang, stack-overflow, hard-fault), else 0. */
uint32_t ug_inject_parse(const char *line);
const char *ug_inject_name(uint32_t kind);

#endif
