/*
 * ug_loop.c - the device-side limiter and the amplitude loop (docs/design.md, "The amplitude loop").
 *
 * Limiter (docs/protocol.md [R-LIMIT]): the drive stays within 0..D (the drive ceiling), or down to -L
 * where the loop's brake allows it (its floor, below); within L (the
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
 *
 * Braking (UG_FEATURE_BRAKING): while the measured amplitude is above the target the loop may drive the
 * carrier in antiphase (a negative drive), which pulls the resonator's phasor down faster than its free
 * decay. The plate's amplitude is the phasor's magnitude: pulled through zero it would grow again in the
 * opposite phase, which a magnitude measurement cannot tell from the right one. So the brake stops before
 * the envelope could cross zero: a second model, the fastest plausible plate (tau / 2, as the limiter's;
 * a slower plate, or one off resonance, falls less), runs on the drive played and is reset to every
 * measurement (delay-compensated); a drive u held for the loop period M (the ADC block and its lag, the
 * longest the plate goes unmeasured) brings that plate from p to a^M p + (1 - a^M) u, so the drive may go
 * no lower than (m - a^M p) / (1 - a^M), recomputed every sample as p falls: that plate only approaches
 * the margin m (UG_BRAKE_MARGIN, above the measurement's noise), and any slower plate stays above it. The
 * limiter keeps a negative drive within minus the limit L, so a brake held for ever would leave the plate at
 * most at L, in either phase.
 *
 * Should the plate still cross (noise beyond the margin, a plate outside the plausible range), the brake
 * would drive the opposite phase up, and the loop, seeing more amplitude, would brake harder. So the
 * measurement is checked: over a block in which the drive braked and never pushed, a plate in the right
 * phase falls at least as fast as the slowest plausible one (2 tau) decays freely; an amplitude above that
 * (plus m) is the opposite phase, and the brake stays off (drive >= 0: the free decay drains either phase)
 * until the measured amplitude has fallen below the target by m.
 */
#include <math.h>

#include "ug_internal.h"

#define UG_LOOP_KI 1000.0f          /* integral gain, per second */
#define UG_LOOP_MIN_APPROACH_S 0.0002f
#define UG_LOOP_APPROACH_BLOCKS 1.2f
#define UG_BRAKE_MARGIN 0.01f       /* the brake stops this far above zero, fraction of full scale */

/* floor: the lowest drive allowed (0, or a brake's, from ug_loop_brake_floor); never below -L */
float ug_limit(ug_core *core, float drive, float floor) {
    float u = drive;
    if (!(floor <= 0.0f)) {
        floor = 0.0f;
    } else if (floor < -core->limit_fraction) {
        floor = -core->limit_fraction;
    }
    if (u != u) { /* NaN: no drive */
        u = 0.0f;
    } else if (u < floor) {
        u = floor;
    }
    if (UG_BROKEN(core, UG_BREAK_LIMIT)) {
        u = u > 1.0f ? 1.0f : u;
    } else if (u > 0.0f) {
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

float ug_loop_brake_floor(const ug_core *core, float target) {
    if (!(core->config.features & UG_FEATURE_BRAKING) || core->loop_mode != 1u) {
        return 0.0f;
    }
    float r = target < core->limit_fraction ? target : core->limit_fraction;
    float d = core->brake_period_decay;
    if (core->brake_inhibit || !(core->measured > r) || !(d < 1.0f)) {
        return 0.0f;
    }
    float floor = (UG_BRAKE_MARGIN - d * core->brake_plate) / (1.0f - d);
    if (!(floor < 0.0f)) {
        return 0.0f;
    }
    return floor > -core->limit_fraction ? floor : -core->limit_fraction;
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
    core->brake_plate += core->fast_gain * (drive - core->brake_plate);
    if (drive > 0.0f) {
        core->brake_pushed = 1u;
    } else if (drive < 0.0f) {
        core->brake_braked = 1u;
    }
    core->hist_head = (uint16_t)((core->hist_head + 1u) & (UG_HISTORY - 1u));
    core->hist_model[core->hist_head] = core->loop_model;
    core->hist_brake[core->hist_head] = core->brake_plate;
    core->hist_target[core->hist_head] = requested < core->limit_fraction ? requested : core->limit_fraction;
}

void ug_loop_measured(ug_core *core, size_t n) {
    unsigned at = (core->hist_head - core->config.sense_delay_samples) & (UG_HISTORY - 1u);
    float measured = core->measured;
    core->loop_model += measured - core->hist_model[at];
    core->brake_plate += core->fast_delay_decay * (measured - core->hist_brake[at]);
    /* the brake's phase check (a lagging measurement: the blocks before count too) */
    unsigned lag_blocks = core->config.sense_delay_samples > 0u;
    bool pushed = core->brake_pushed || (lag_blocks && core->brake_prev_pushed);
    float slowest_free = core->brake_last * expf(0.5f * (float)n * logf(core->model_decay));
    if (core->brake_braked && !pushed && measured > slowest_free + UG_BRAKE_MARGIN) {
        core->brake_inhibit = 1u;
    } else if (core->brake_inhibit && measured < core->hist_target[at] - UG_BRAKE_MARGIN) {
        core->brake_inhibit = 0u;
    }
    core->brake_last = measured;
    core->brake_prev_pushed = core->brake_pushed;
    core->brake_pushed = core->brake_braked = 0u;
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
    /* the fastest plate's decay over a loop period: the brake's reach */
    core->brake_period_decay = expf((float)(n + core->config.sense_delay_samples) * logf(1.0f - core->fast_gain));
}

void ug_loop_reset(ug_core *core) {
    core->loop_integral = 0.0f;
    core->loop_saturated = 0;
    core->loop_model = core->measured;
    core->brake_plate = core->measured;
    core->brake_last = core->measured;
    core->brake_pushed = core->brake_braked = core->brake_prev_pushed = 0u;
    if (core->loop_approach <= 0.0f) {
        core->loop_approach = 1.0f - expf(-1.0f / ((float)core->config.sample_rate_hz * UG_LOOP_MIN_APPROACH_S));
    }
}
