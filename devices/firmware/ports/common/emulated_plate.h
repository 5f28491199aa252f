/*
 * The plate the QEMU image drives: QEMU models no DAC, no ADC signal and no piezo, so the QEMU image
 * plays each block of DAC codes into this model and reads its sensing piezo back as ADC codes, which
 * the port then measures exactly as it measures the real ADC's. The plate is a resonator driven by the
 * carrier itself, sample by sample at the DAC rate: a two-pole filter whose poles sit at the plate's
 * resonance f0 (drifting D Hz/s) with radius exp(-pi f0 / (Q fs)), so that its envelope answers a step
 * of drive as a first-order low-pass of time constant tau = Q / (pi f0) and its steady amplitude at a
 * carrier fc is, near f0, 1/sqrt(1 + (2Q (fc - f0) / f0)^2) of that at resonance: the simulated
 * plate's physics (devices/sim/plate.py, DESIGN.md), reached here through the carrier rather than its
 * envelope. Full drive at resonance settles at full_scale_um_pp peak-to-peak. Pure arithmetic, tested
 * on the host (tests/test_firmware_board.py).
 */
#ifndef UG_EMULATED_PLATE_H
#define UG_EMULATED_PLATE_H

#include <stdint.h>

#define UG_DAC_MID 2048.0f            /* 12-bit DAC and ADC: mid-scale is no drive, no motion */
#define UG_DAC_AMPLITUDE 2047.9375f   /* DAC codes of full-scale drive: 32767 / 16 */
#define UG_DAC_WORD_MID 32768.0f      /* the same for the DAC's left-aligned words: 16 x the codes */

typedef struct {
    float resonance_hz;      /* f0 at start */
    float q;
    float drift_hz_per_s;
    float full_scale_um_pp;  /* steady amplitude at full drive at resonance */
    float sample_rate_hz;    /* DAC and ADC samples a second */
    float um_pp_per_code;    /* the sensing ADC's scale: um p-p per code of p-p swing */
    float elapsed_s;
    float y1, y2;            /* the displacement, um from rest, at the last two samples */
    float peak_um_pp;        /* twice the largest displacement reached: the plate's own peak-to-peak */
} ug_emulated_plate_t;

void ug_emulated_plate_init(ug_emulated_plate_t *plate, float resonance_hz, float q, float drift_hz_per_s,
                            float full_scale_um_pp, float sample_rate_hz, float um_pp_per_code);

/* f0 now (drifted), at least 1 Hz. */
float ug_emulated_plate_resonance_hz(const ug_emulated_plate_t *plate);

/* Play n DAC words (DHR12L1's left-aligned codes: the DAC converts bits 15:4) into the plate and sample its
   sensing piezo as n ADC codes (0..4095 around mid-scale). */
void ug_emulated_plate_run(ug_emulated_plate_t *plate, const uint16_t *dac, uint16_t *adc, uint32_t n);

#endif
