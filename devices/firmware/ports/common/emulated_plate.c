#include "emulated_plate.h"

#include <math.h>

void ug_emulated_plate_init(ug_emulated_plate_t *plate, float resonance_hz, float q, float drift_hz_per_s,
                            float full_scale_um_pp, float sample_rate_hz, float um_pp_per_code)
{
    plate->resonance_hz = resonance_hz;
    plate->q = q;
    plate->drift_hz_per_s = drift_hz_per_s;
    plate->full_scale_um_pp = full_scale_um_pp;
    plate->sample_rate_hz = sample_rate_hz;
    plate->um_pp_per_code = um_pp_per_code;
    plate->elapsed_s = 0.0f;
    plate->y1 = plate->y2 = 0.0f;
    plate->peak_um_pp = 0.0f;
}

float ug_emulated_plate_resonance_hz(const ug_emulated_plate_t *plate)
{
    float f0 = plate->resonance_hz + plate->drift_hz_per_s * plate->elapsed_s;
    return f0 < 1.0f ? 1.0f : f0;
}

/*
 * y[n] = a1 y[n-1] - a2 y[n-2] + b x[n], poles r e^{+-j theta}: theta = 2 pi f0 / fs, r = exp(-pi f0 / (Q fs)).
 * Its gain at theta is b / |D| with |D| = (1 - r) sqrt((1 + r - 2 r c^2)^2 + (2 r c s)^2) (c, s: cos and sin
 * of theta), so b = |D| full_scale / 2 makes full drive (x of amplitude 1) swing full_scale um peak-to-peak.
 */
void ug_emulated_plate_run(ug_emulated_plate_t *plate, const uint16_t *dac, uint16_t *adc, uint32_t n)
{
    float f0 = ug_emulated_plate_resonance_hz(plate);
    float theta = 6.2831853f * f0 / plate->sample_rate_hz;
    float decay = 3.14159265f * f0 / (plate->q * plate->sample_rate_hz);
    float r = expf(-decay), one_minus_r = -expm1f(-decay);
    float c = cosf(theta), s = sinf(theta);
    float re = 1.0f + r - 2.0f * r * c * c, im = 2.0f * r * c * s;
    float b = 0.5f * plate->full_scale_um_pp * one_minus_r * sqrtf(re * re + im * im) / UG_DAC_AMPLITUDE;
    float a1 = 2.0f * r * c, a2 = r * r;
    float per_code = 1.0f / plate->um_pp_per_code;
    float y1 = plate->y1, y2 = plate->y2, largest = 0.5f * plate->peak_um_pp;
    for (uint32_t i = 0; i < n; i++) {
        float y = a1 * y1 - a2 * y2 + b * ((float)(dac[i] >> 4) - UG_DAC_MID);  /* the 12 bits converted */
        y2 = y1;
        y1 = y;
        float magnitude = fabsf(y);
        largest = magnitude > largest ? magnitude : largest;
        float code = UG_DAC_MID + y * per_code;
        code = code < 0.0f ? 0.0f : (code > 4095.0f ? 4095.0f : code);
        adc[i] = (uint16_t)(code + 0.5f);
    }
    plate->y1 = y1;
    plate->y2 = y2;
    plate->peak_um_pp = 2.0f * largest;
    plate->elapsed_s += (float)n / plate->sample_rate_hz;
}
