/*
 * ug_state.c - the output's state over time: ENABLE and DISABLE, the stream started and stopped,
 * overheat, the watchdog, and the 1 ms tick that also schedules TELEMETRY and SENSORS.
 */
#include "ug_internal.h"

#define STREAM_GAP_MS 50u /* no SETPOINTS for this long: the stream has stopped (an event, not a fault) */

/* ---- output state ------------------------------------------------------------------------------------ */
void ug_stop_stream(ug_core *core) {
    if (core->streaming) {
        core->streaming = 0;
        ug_post_event(core, UG_EV_STREAM_STOPPED, 0, 0, 0.0f);
    }
}

void ug_forget_stream(ug_core *core) {
    ug_buffer_clear(core);
    core->have_expected = 0;
    if (!UG_BROKEN(core, UG_BREAK_RATE)) {
        core->rate = 0;
    }
}

void ug_disable(ug_core *core, uint8_t why) {
    bool was = core->state != UG_OFF;
    core->state = UG_OFF;
    ug_forget_stream(core);
    core->drive = core->current = core->next = core->hold = 0.0f;
    core->ramp_left = 0;
    ug_stop_stream(core);
    ug_loop_reset(core);
    ug_port_output_safe(core->port, UG_SAFE_DISABLE);
    if (was) {
        ug_post_event(core, UG_EV_DISABLED, why, 0, 0.0f);
    }
}

void ug_enable(ug_core *core) {
    core->state = UG_PREFILL;
    if (!UG_BROKEN(core, UG_BREAK_DISCARD)) {
        ug_forget_stream(core);
    }
    core->have_expected = 0;
    core->last_frame_ms = core->now_ms;
    core->watchdog_fired = 0;
    core->drive = core->current = core->next = core->hold = 0.0f;
    ug_loop_reset(core);
    ug_post_event(core, UG_EV_ENABLED, 0, 0, 0.0f);
}

void ug_overheat(ug_core *core) {
    ug_raise_fault(core, UG_FAULT_OVERHEAT, 0, 0.0f);
    ug_disable(core, UG_WHY_OVERHEAT);
}

void ug_core_set_stage_hot(ug_core *core, bool hot) {
    ug_port_critical_enter(core->port);
    if (hot && !core->stage_hot) {
        core->stage_hot = 1;
        core->hot_until_ms = 0;
        ug_overheat(core);
    } else if (!hot) {
        core->stage_hot = 0;
    }
    ug_port_critical_exit(core->port);
}

size_t ug_core_block(ug_core *core, const float *amplitude_um_pp, const float *normal_force_n,
                     const float *lateral_force_n, size_t n, int16_t *dac, size_t n_dac) {
    size_t cut = ug_core_adc_block(core, amplitude_um_pp, normal_force_n, lateral_force_n, n);
    ug_core_dac_block(core, dac, n_dac);
    ug_core_tick(core);
    return cut;
}

void ug_core_lost_time(ug_core *core, uint32_t ms) {
    for (uint32_t i = 0; i < ms; i++) {
        ug_core_tick(core);
    }
    core->lost_ms += ms;
}

/* ---- time ------------------------------------------------------------------------------------------- */
static void fire_watchdog(ug_core *core) {
    core->watchdog_fired = 1;
    ug_raise_fault(core, UG_FAULT_WATCHDOG, 0, 0.0f);
    core->ramp_from = core->drive > 0.0f ? core->drive : 0.0f; /* a brake (antiphase) stops at once */
    core->ramp_samples = core->config.sample_rate_hz / 1000u * UG_WATCHDOG_RAMP_MS;
    core->ramp_left = core->ramp_samples;
    ug_buffer_clear(core); /* the stream (rate, expected) stays */
    core->state = UG_RAMP;
    ug_stop_stream(core);
    ug_loop_reset(core);
}

void ug_core_tick(ug_core *core) {
    core->now_ms++;
    if (core->stage_hot && core->hot_until_ms != 0u && (int32_t)(core->now_ms - core->hot_until_ms) >= 0) {
        core->stage_hot = 0;
    }
    if (core->state != UG_OFF && !core->watchdog_fired) {
        uint32_t timeout = core->config.watchdog_ms * (UG_BROKEN(core, UG_BREAK_WATCHDOG) ? 3u : 1u);
        if ((int32_t)(core->now_ms - core->last_frame_ms) >= (int32_t)timeout) { /* signed: see ug_sim_receive */
            fire_watchdog(core);
        }
    }
    if (UG_BROKEN(core, UG_BREAK_UNDERRUN) && core->state == UG_DRY) {
        ug_raise_fault(core, UG_FAULT_UNDERRUN, 0, 0.0f);
    }
    if (UG_BROKEN(core, UG_BREAK_OVER_LIMIT) && core->measured_um_pp > core->config.max_amplitude_um_pp) {
        ug_raise_fault(core, UG_FAULT_OVER_LIMIT, 0, core->measured_um_pp);
    }
    if (core->streaming && (int32_t)(core->now_ms - core->last_setpoints_ms) >= (int32_t)STREAM_GAP_MS) {
        ug_stop_stream(core);
    }
    if ((int32_t)(core->now_ms - core->telemetry_due_ms) >= 0) {
        core->telemetry_due = 1;
        core->telemetry_due_ms = core->now_ms + core->telemetry_period_ms * (UG_BROKEN(core, UG_BREAK_TELEMETRY) ? 2u : 1u);
    }
    if (core->config.sensors) {
        uint32_t period = core->state != UG_OFF ? UG_SENSORS_PERIOD_MS : UG_SENSORS_REST_PERIOD_MS;
        if ((core->now_ms - core->sensors_due_ms >= period && core->sensor_pending > 0u) ||
            core->sensor_pending >= UG_MAX_SENSOR_SAMPLES - 8u) {
            core->sensors_due = 1;
            core->sensors_due_ms = core->now_ms;
        }
    }
}
