/* ug_sense.c - the measurements: over-limit and trip on every ADC sample, SENSORS samples decimated. */
#include <math.h>

#include "ug_internal.h"

/* ---- measurements ------------------------------------------------------------------------------------ */
/* the stream index that played `age` drive samples before the newest (UG_NOT_PLAYING beyond the history) */
static uint32_t index_at(const ug_core *core, size_t age) {
    if (age >= UG_HISTORY) {
        return core->state == UG_PLAYING ? core->play_index : UG_NOT_PLAYING;
    }
    return core->hist_index[(core->hist_head - age) & (UG_HISTORY - 1u)];
}

static void sense_sample(ug_core *core, float amplitude, float normal, float lateral, size_t age) {
    if (core->sensor_count_in == 0u) {
        core->sensor_first_index = index_at(core, age);
        core->sensor_sum[0] = core->sensor_sum[1] = core->sensor_sum[2] = 0.0f;
    }
    core->sensor_sum[0] += amplitude;
    core->sensor_sum[1] += normal;
    core->sensor_sum[2] += lateral;
    if (++core->sensor_count_in < core->sensor_decimation) {
        return;
    }
    core->sensor_count_in = 0;
    if (core->sensor_pending >= UG_MAX_SENSOR_SAMPLES) { /* not sent in time (a v2 host, a hung link) */
        core->sensor_pending = 0;
    }
    float scale = 1.0f / (float)core->sensor_decimation;
    const uint8_t bits[3] = {UG_SENSOR_AMPLITUDE, UG_SENSOR_NORMAL_FORCE, UG_SENSOR_LATERAL_FORCE};
    for (unsigned k = 0; k < 3u; k++) {
        core->sensor_ring[core->sensor_active][core->sensor_pending].value[k] =
            (core->config.sensors & bits[k]) ? core->sensor_sum[k] * scale : NAN;
    }
    core->sensor_ring[core->sensor_active][core->sensor_pending].index = core->sensor_first_index;
    core->sensor_pending++;
    core->sensor_next++;
}

size_t ug_core_adc_block(ug_core *core, const float *amplitude_um_pp, const float *normal_force_n,
                         const float *lateral_force_n, size_t n) {
    size_t cut = n;
    const float limit = core->config.max_amplitude_um_pp;
    for (size_t i = 0; i < n; i++) {
        float measured = amplitude_um_pp != NULL ? amplitude_um_pp[i] : 0.0f;
        if (!isfinite(measured)) {
            measured = 0.0f;
        }
        if (measured > limit) {
            if (core->over_armed && !UG_BROKEN(core, UG_BREAK_OVER_LIMIT)) {
                ug_raise_fault(core, UG_FAULT_OVER_LIMIT, 0, measured);
            }
            core->over_armed = 0;
        } else if (measured < core->rearm_um_pp) {
            core->over_armed = 1;
        }
        if (measured > core->trip_um_pp && core->state != UG_OFF) {
            ug_raise_fault(core, UG_FAULT_TRIP, 0, measured);
            ug_disable(core, UG_WHY_TRIP);
            if (cut == n) {
                cut = i;
            }
        }
        core->measured_um_pp = measured;
        if (core->sensor_decimation) {
            sense_sample(core, measured, normal_force_n != NULL ? normal_force_n[i] : NAN,
                         lateral_force_n != NULL ? lateral_force_n[i] : NAN,
                         n - 1u - i + core->config.sense_delay_samples);
        }
    }
    core->measured = core->measured_um_pp / core->config.full_scale_um_pp;
    if (normal_force_n != NULL && (core->config.features & UG_FEATURE_FORCE_CORRECTION)) {
        ug_force_measured(core, normal_force_n, n);
    }
    if (n > 0u) {
        ug_loop_measured(core, n);
    }
    return cut;
}
