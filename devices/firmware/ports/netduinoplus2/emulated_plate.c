#include "emulated_plate.h"

#include <math.h>

void ug_emulated_plate_init(ug_emulated_plate_t *plate, float resonance_hz, float q, float drift_hz_per_s,
                            float full_scale_um_pp)
{
    plate->resonance_hz = resonance_hz;
    plate->q = q;
    plate->drift_hz_per_s = drift_hz_per_s;
    plate->full_scale_um_pp = full_scale_um_pp;
    plate->elapsed_s = 0.0f;
    plate->amplitude_um_pp = 0.0f;
}

float ug_emulated_plate_resonance_hz(const ug_emulated_plate_t *plate)
{
    float f0 = plate->resonance_hz + plate->drift_hz_per_s * plate->elapsed_s;
    return f0 < 1.0f ? 1.0f : f0;
}

float ug_emulated_plate_gain(const ug_emulated_plate_t *plate, float carrier_hz)
{
    float f0 = ug_emulated_plate_resonance_hz(plate);
    float detuning = 2.0f * plate->q * (carrier_hz - f0) / f0;
    return 1.0f / sqrtf(1.0f + detuning * detuning);
}

float ug_emulated_plate_step(ug_emulated_plate_t *plate, float drive, float carrier_hz, float dt_s)
{
    float f0 = ug_emulated_plate_resonance_hz(plate);
    float tau_s = plate->q / (3.14159265f * f0);
    float target = drive * plate->full_scale_um_pp * ug_emulated_plate_gain(plate, carrier_hz);
    float decay = expf(-dt_s / tau_s);
    plate->amplitude_um_pp = target + (plate->amplitude_um_pp - target) * decay;
    plate->elapsed_s += dt_s;
    return plate->amplitude_um_pp;
}
