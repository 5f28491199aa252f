/*
 * ug_loop.c - the device-side limiter and the amplitude loop (docs/design.md, "The amplitude loop").
 *
 * Limiter (docs/protocol.md [R-LIMIT]): the drive stays within 0..D (the drive ceiling); within L (the
 * limit's share of full scale) once the measured amplitude reaches the limit; and within what keeps
 * the fastest plausible plate (a first-order envelope with half the configured Q) at or below L:
 * u <= p + (L - p) / g with p that model's envelope and g its per-sample gain. A slower plate, or one
 * driven off resonance, responds less, so no plate within a factor two of the configured Q can be
 * driven above its limit, whatever the measurement's latency.
 *
 * Loop: setpoints are amplitude targets r. Per drive sample the loop asks of a first-order model of the
 * plate (the configured tau: decay a per sample) that it move a fraction lambda of the way to r:
 * u = (y + lambda (r - y) - a y) / (1 - a) + I, where y is the model's envelope, reset to the measured
 * amplitude at every ADC block (delay-compensated: the model's own value at the measured sample is
 * replaced by the measurement, a Smith predictor), and I integrates the measured error r - y_measured
 * (gain UG_LOOP_KI per second) for a plate whose gain differs from the model's, frozen while the drive
 * saturates in the error's direction (no wind-up). lambda's time constant follows the ADC block: the
 * longer the plate goes unmeasured, the gentler the approach (max(0.2 ms, 1.2 x block)).
 */
#include <math.h>

#include "ug_internal.h"

#define UG_LOOP_KI 1000.0f          /* integral gain, per second */
#define UG_LOOP_MIN_APPROACH_S 0.0002f
#define UG_LOOP_APPROACH_BLOCKS 1.2f

float ug_limit(ug_core *core, float drive) {
    float u = drive;
    if (!(u > 0.0f)) { /* negative, zero or NaN */
        u = 0.0f;
    }
    if (UG_BROKEN(core, UG_BREAK_LIMIT)) {
        u = u > 1.0f ? 1.0f : u;
    } else {
        float ceiling = core->measured_um_pp >= core->config.max_amplitude_um_pp ? core->limit_fraction
                                                                                   : core->drive_ceiling;
        if (u > ceiling) {
            u = ceiling;
        }
        float fast = core->fast_plate;
        float bound = fast + (core->limit_fraction - fast) / core->fast_gain;
        if (u > bound) {
            u = bound > 0.0f ? bound : 0.0f;
        }
    }
    core->fast_plate += core->fast_gain * (u - core->fast_plate);
    return u;
}

float ug_loop_drive(ug_core *core, float target) {
    float r = target < core->limit_fraction ? target : core->limit_fraction;
    if (r < 0.0f) {
        r = 0.0f;
    }
    float y = core->loop_model;
    float a = core->model_decay;
    float want = y + core->loop_approach * (r - y);
    return (want - a * y) / (1.0f - a) + core->loop_integral;
}

/* after the limiter: the model follows the drive actually played; the history keeps it for alignment */
void ug_loop_record(ug_core *core, float requested, float drive) {
    float wanted_above = 0.0f;
    if (core->loop_mode == 1u && core->state != UG_RAMP && core->state != UG_OFF && core->state != UG_PREFILL) {
        float r = requested < core->limit_fraction ? requested : core->limit_fraction;
        float y = core->loop_model;
        float u = (y + core->loop_approach * (r - y) - core->model_decay * y) / (1.0f - core->model_decay) +
                  core->loop_integral;
        wanted_above = u - drive;
        if (wanted_above > 1e-6f) {
            core->loop_saturated |= 1u;
        } else if (wanted_above < -1e-6f) {
            core->loop_saturated |= 2u;
        }
    }
    core->loop_model = core->model_decay * core->loop_model + (1.0f - core->model_decay) * drive;
    core->hist_head = (uint16_t)((core->hist_head + 1u) & (UG_HISTORY - 1u));
    core->hist_model[core->hist_head] = core->loop_model;
    core->hist_target[core->hist_head] = requested < core->limit_fraction ? requested : core->limit_fraction;
}

void ug_loop_measured(ug_core *core, size_t n) {
    unsigned at = (core->hist_head - core->config.sense_delay_samples) & (UG_HISTORY - 1u);
    float measured = core->measured;
    core->loop_model += measured - core->hist_model[at];
    if (core->loop_mode == 1u && (core->state == UG_PLAYING || core->state == UG_DRY)) {
        float error = core->hist_target[at] - measured;
        bool frozen = ((core->loop_saturated & 1u) && error > 0.0f) || ((core->loop_saturated & 2u) && error < 0.0f);
        if (!frozen) {
            float integral = core->loop_integral + UG_LOOP_KI * error * (float)n / (float)core->config.sample_rate_hz;
            core->loop_integral = integral > 1.0f ? 1.0f : (integral < -1.0f ? -1.0f : integral);
        }
    }
    core->loop_saturated = 0;
    float block_s = (float)(n + core->config.sense_delay_samples) / (float)core->config.sample_rate_hz;
    float approach_s = UG_LOOP_APPROACH_BLOCKS * block_s;
    if (approach_s < UG_LOOP_MIN_APPROACH_S) {
        approach_s = UG_LOOP_MIN_APPROACH_S;
    }
    core->loop_approach = 1.0f - expf(-1.0f / ((float)core->config.sample_rate_hz * approach_s));
}

void ug_loop_reset(ug_core *core) {
    core->loop_integral = 0.0f;
    core->loop_saturated = 0;
    core->loop_model = core->measured;
    if (core->loop_approach <= 0.0f) {
        core->loop_approach = 1.0f - expf(-1.0f / ((float)core->config.sample_rate_hz * UG_LOOP_MIN_APPROACH_S));
    }
}
