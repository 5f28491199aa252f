/*
 * The plate the QEMU image drives: QEMU models no DAC, no ADC signal and no piezo, so the QEMU image
 * feeds the core's sensing input from this model instead of the ADC. It is the simulated plate's
 * physics (devices/plate_sim.py, DESIGN.md): a resonance f0 drifting D Hz/s with quality factor Q,
 * steady gain 1/sqrt(1 + (2Q(fc − f0)/f0)²) at carrier fc, and an envelope that follows the drive as
 * a first-order low-pass of time constant τ = Q/(π f0). Pure arithmetic, tested on the host.
 */
#ifndef UG_EMULATED_PLATE_H
#define UG_EMULATED_PLATE_H

typedef struct {
    float resonance_hz;      /* f0 at start */
    float q;
    float drift_hz_per_s;
    float full_scale_um_pp;  /* steady amplitude at full drive at resonance */
    float elapsed_s;
    float amplitude_um_pp;   /* the envelope now */
} ug_emulated_plate_t;

void ug_emulated_plate_init(ug_emulated_plate_t *plate, float resonance_hz, float q, float drift_hz_per_s,
                            float full_scale_um_pp);

/* f0 now (drifted), at least 1 Hz. */
float ug_emulated_plate_resonance_hz(const ug_emulated_plate_t *plate);

/* Steady amplitude at carrier_hz relative to that at resonance. */
float ug_emulated_plate_gain(const ug_emulated_plate_t *plate, float carrier_hz);

/* Advance dt_s with the drive held at drive (fraction of full scale, 0..1) at carrier_hz; returns the
   amplitude, µm peak-to-peak. Exact for a constant drive over the step. */
float ug_emulated_plate_step(ug_emulated_plate_t *plate, float drive, float carrier_hz, float dt_s);

#endif
