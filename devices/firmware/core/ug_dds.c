/*
 * ug_dds.c - the carrier: a phase-accumulator DDS (32-bit phase, a 256-step sine table with linear
 * interpolation: spurs below -90 dBc), amplitude-modulated by the drive, interpolated linearly between
 * drive samples. SET_CARRIER changes only the phase step, so the carrier stays phase-continuous.
 */
#include <math.h>

#include "ug_internal.h"

#include "sine_table.inc"

void ug_dds_set(ug_core *core, float carrier_hz) {
    double dac_hz = (double)core->config.sample_rate_hz * core->config.dac_oversample;
    core->carrier_hz = carrier_hz;
    core->carrier_step = (uint32_t)((double)carrier_hz / dac_hz * 4294967296.0 + 0.5);
}

static inline float sine(uint32_t phase) {
    uint32_t i = phase >> 24;
    float frac = (float)((phase >> 8) & 0xFFFFu) * (1.0f / 65536.0f);
    float a = sine_table[i], b = sine_table[i + 1u];
    return a + (b - a) * frac;
}

/* n_dac carrier samples (int16, +-32767 at full-scale drive); n_dac a multiple of dac_oversample */
void ug_core_dac_block(ug_core *core, int16_t *out, size_t n_dac) {
    const unsigned over = core->config.dac_oversample;
    const float step = 1.0f / (float)over;
    size_t drive_samples = n_dac / over;
    size_t written = 0;
    while (drive_samples > 0u) {
        size_t chunk = drive_samples < UG_MAX_BLOCK ? drive_samples : UG_MAX_BLOCK;
        ug_core_drive_block(core, core->scratch, chunk);
        for (size_t j = 0; j < chunk; j++) {
            float from = core->dac_last, to = core->scratch[j];
            for (unsigned k = 1; k <= over; k++) {
                float amplitude = from + (to - from) * step * (float)k;
                float s = amplitude * sine(core->carrier_phase);
                core->carrier_phase += core->carrier_step;
                out[written++] = (int16_t)(s >= 0.0f ? s + 0.5f : s - 0.5f);
            }
            core->dac_last = to;
        }
        drive_samples -= chunk;
    }
    while (written < n_dac) {
        out[written++] = 0; /* a remainder shorter than one drive sample: silence */
    }
}
