/*
 * The QEMU image's emulation block: the emulated plate's truth and the profile the firmware declares.
 * It sits in flash in its own ELF section, ``.emulation``, holding the sim-plate defaults;
 * devices/firmware/qemu.py (EmulatedPlate) writes other values into a copy of the ELF file before QEMU
 * loads it. (QEMU 7.2's generic loader cannot be used instead: with it present the Cortex-M reset reads
 * its stack pointer and entry point before the image is in memory.) The hardware image has no such block.
 */
#ifndef UG_EMULATION_CONFIG_H
#define UG_EMULATION_CONFIG_H

#include <stdint.h>

#define UG_EMULATION_MAGIC 0x55474550u  /* "UGEP" */

typedef struct {
    uint32_t magic;
    float resonance_hz;          /* the emulated plate's truth */
    float q;
    float drift_hz_per_s;
    float profile_resonance_hz;  /* what the firmware declares in HELLO_REPLY ... */
    float profile_q;             /* ... and believes (its limiter's and amplitude loop's model) */
    float full_scale_um_pp;
    float max_amplitude_um_pp;
    float max_drive_um_pp;
    float carrier_min_hz;
    float carrier_max_hz;
} ug_emulation_config_t;

/* The block; volatile so that the compiler never folds its defaults into the code. */
extern const volatile ug_emulation_config_t ug_emulation;

#endif
