/*
 * ug_core.c - the core's configuration and start, its events and faults, its status: the protocol state
 * machine of docs/protocol.md (version 3, and version 2's layouts) is in the files beside it, by job:
 * ug_commands.c (frames from the host), ug_tx.c (frames to the host), ug_state.c (enable, disable, the
 * watchdog, the 1 ms tick), ug_playback.c (the jitter buffer and one drive sample), ug_sense.c (the
 * measurements and SENSORS samples); ug_frame.c, ug_dds.c and ug_loop.c as before.
 *
 * Contexts (ug_port.h): ug_core_uart_rx in the UART interrupt; ug_core_tick, ug_core_drive_block,
 * ug_core_dac_block and ug_core_adc_block in interrupts of one priority; ug_core_poll in the main loop,
 * which handles each frame inside a critical section. Nothing here allocates or blocks; every loop is
 * bounded by a block, a frame or a ring.
 */
#include <math.h>
#include <string.h>

#include "ug_internal.h"

static const char *const rule_names[UG_BREAKS] = {
    "R-FRAMING", "R-CRC", "R-DEVICE-SEQ", "R-SEQ-ECHO", "R-VERSION", "R-HELLO-NO-STATE", "R-NAK-ORDER",
    "R-NAK-NO-EFFECT", "R-ACK", "R-CARRIER", "R-TELEMETRY", "R-SENSORS", "R-RATE", "R-EXPECTED", "R-OVERRUN",
    "R-PREFILL", "R-UNDERRUN", "R-DISCARD", "R-ENABLE", "R-LIMIT", "R-OVER-LIMIT", "R-WATCHDOG",
    "R-FAULT-LATCH", "R-FAULT-COUNT", "R-CLEAR-FAULTS", "R-LOOP", "R-CLOCK",
};

const char *ug_break_rule(unsigned which) { return which < UG_BREAKS ? rule_names[which] : NULL; }

#define LOOP_NONE 0xFFu

/* ---- configuration ------------------------------------------------------------------------------- */
void ug_config_defaults(ug_config *config) {
    memset(config, 0, sizeof *config);
    config->resonance_hz = 25000.0f;
    config->q = 200.0f;
    config->full_scale_um_pp = 8.0f;
    config->max_amplitude_um_pp = 6.0f;
    config->max_drive_um_pp = 8.0f;
    config->carrier_min_hz = 20000.0f;
    config->carrier_max_hz = 28000.0f;
    config->carrier_hz = 25000.0f;
    config->min_setpoint_rate_hz = 1000u;
    config->max_setpoint_rate_hz = 48000u;
    config->watchdog_ms = UG_WATCHDOG_MS;
    config->buffer_ms = UG_BUFFER_MS;
    config->sample_rate_hz = 48000u;
    config->dac_oversample = 4u;
    config->sensors = UG_SENSOR_AMPLITUDE;
    config->sensor_rate_hz = 1000u;
    config->features = UG_FEATURE_AMPLITUDE_LOOP;
    config->max_version = UG_PROTOCOL_VERSION;
    config->sim_faults = 0u;
    config->sense_delay_samples = 0u;
    memcpy(config->name, "ultraglide reference firmware", sizeof "ultraglide reference firmware");
}

static bool finite_positive(float x) { return isfinite(x) && x > 0.0f; }

static bool config_ok(const ug_config *c) {
    if (!finite_positive(c->resonance_hz) || !finite_positive(c->q) || !finite_positive(c->full_scale_um_pp) ||
        !finite_positive(c->max_amplitude_um_pp) || !isfinite(c->max_drive_um_pp) ||
        !finite_positive(c->carrier_min_hz) || !isfinite(c->carrier_max_hz) || !isfinite(c->carrier_hz)) {
        return false;
    }
    if (c->max_amplitude_um_pp > c->full_scale_um_pp || c->max_drive_um_pp < c->max_amplitude_um_pp ||
        c->max_drive_um_pp > c->full_scale_um_pp || c->carrier_max_hz < c->carrier_min_hz ||
        c->carrier_hz < c->carrier_min_hz || c->carrier_hz > c->carrier_max_hz) {
        return false;
    }
    if (c->sample_rate_hz < 1000u || c->sample_rate_hz % 1000u != 0u || c->sample_rate_hz > 1000000u ||
        c->min_setpoint_rate_hz < 1u || c->min_setpoint_rate_hz > c->max_setpoint_rate_hz ||
        c->max_setpoint_rate_hz > c->sample_rate_hz) {
        return false;
    }
    if (c->watchdog_ms < 20u || c->watchdog_ms > 1000u || c->buffer_ms < 50u || c->buffer_ms > 1000u ||
        (uint64_t)c->buffer_ms * c->max_setpoint_rate_hz / 1000u > UG_BUFFER_CAPACITY ||
        (uint64_t)UG_PREFILL_MS * c->max_setpoint_rate_hz / 1000u + 1u > UG_BUFFER_CAPACITY) {
        return false;
    }
    if (c->dac_oversample < 1u || c->dac_oversample > 16u || c->sense_delay_samples >= UG_HISTORY) {
        return false;
    }
    if (c->sensors & ~(UG_SENSOR_AMPLITUDE | UG_SENSOR_NORMAL_FORCE | UG_SENSOR_LATERAL_FORCE)) {
        return false;
    }
    if (c->sensors && (c->sensor_rate_hz < UG_MIN_SENSOR_RATE_HZ || c->sample_rate_hz % c->sensor_rate_hz != 0u)) {
        return false;
    }
    if ((c->features & ~(UG_FEATURE_AMPLITUDE_LOOP | UG_FEATURE_BRAKING | UG_FEATURE_FORCE_CORRECTION)) ||
        ((c->features & UG_FEATURE_AMPLITUDE_LOOP) && !(c->sensors & UG_SENSOR_AMPLITUDE)) ||
        ((c->features & UG_FEATURE_BRAKING) && !(c->features & UG_FEATURE_AMPLITUDE_LOOP)) ||
        ((c->features & UG_FEATURE_FORCE_CORRECTION) && !(c->sensors & UG_SENSOR_NORMAL_FORCE))) {
        return false;
    }
    if (c->max_version < UG_LOWEST_VERSION || c->max_version > UG_PROTOCOL_VERSION || c->sim_faults > 1u) {
        return false;
    }
    if (c->reset_stated > 1u || c->reset_reason >= UG_RESTART_REASONS ||
        (c->features & (UG_FEATURE_RESET_STATED | UG_FEATURE_CLOCK_STATED))) {
        return false; /* the feature bits are the core's to set, from reset_stated and sensors */
    }
    return memchr(c->name, 0, sizeof c->name) != NULL;
}

int ug_core_init(ug_core *core, const ug_config *config, void *port) {
    if (core == NULL || config == NULL || !config_ok(config)) {
        return UG_BAD_CONFIG;
    }
    memset(core, 0, sizeof *core);
    core->config = *config;
    core->port = port;
    const float fs = (float)config->sample_rate_hz;
    const float tau = config->q / (3.14159265f * config->resonance_hz);
    core->limit_fraction = config->max_amplitude_um_pp / config->full_scale_um_pp;
    core->drive_ceiling = config->max_drive_um_pp / config->full_scale_um_pp;
    core->trip_um_pp = config->max_amplitude_um_pp * (1.0f + UG_TRIP_MARGIN);
    core->rearm_um_pp = config->max_amplitude_um_pp * UG_OVER_LIMIT_REARM;
    core->fast_gain = 1.0f - expf(-1.0f / (fs * 0.5f * tau));
    core->model_decay = expf(-1.0f / (fs * tau));
    core->fast_delay_decay = expf(-(float)config->sense_delay_samples / (fs * 0.5f * tau));
    core->telemetry_period_ms = 1000u / UG_TELEMETRY_HZ;
    core->session = config->max_version;
    core->state = UG_OFF;
    core->over_armed = 1u;
    core->telemetry_due_ms = 0u; /* the first TELEMETRY at the first tick, the next one a period later */
    core->sensor_decimation = config->sensors ? config->sample_rate_hz / config->sensor_rate_hz : 0u;
    ug_decoder_reset(&core->decoder);
    ug_dds_set(core, config->carrier_hz);
    ug_loop_reset(core);
    core->force_now_n = NAN;
    ug_force_clear(core);
    return UG_OK;
}

bool ug_core_set_breaks(ug_core *core, uint32_t breaks) {
#if defined(UG_CONFORMANCE_BREAKS) && UG_CONFORMANCE_BREAKS
    if (breaks >> UG_BREAKS) {
        return false;
    }
    core->breaks = breaks;
    return true;
#else
    (void)core;
    return breaks == 0u;
#endif
}

/* ---- events and faults ----------------------------------------------------------------------------- */
void ug_post_event(ug_core *core, uint8_t kind, uint8_t a, uint16_t b, float value) {
    if (core->event_count >= UG_EVENTS) {
        core->events_dropped++;
        return;
    }
    ug_event *e = &core->events[(core->event_head + core->event_count) & (UG_EVENTS - 1u)];
    e->sample = core->samples;
    e->time_ms = core->now_ms;
    e->kind = kind;
    e->a = a;
    e->b = b;
    e->value = value;
    core->event_count++;
}

bool ug_core_next_event(ug_core *core, ug_event *out) {
    bool got = false;
    ug_port_critical_enter(core->port);
    if (core->event_count > 0u) {
        *out = core->events[core->event_head];
        core->event_head = (uint16_t)((core->event_head + 1u) & (UG_EVENTS - 1u));
        core->event_count--;
        got = true;
    }
    ug_port_critical_exit(core->port);
    return got;
}

static unsigned bit_index(uint16_t bit) {
    unsigned i = 0;
    while (i < 15u && !(bit & (1u << i))) {
        i++;
    }
    return i;
}

void ug_raise_fault(ug_core *core, uint16_t bit, uint16_t detail, float value) {
    unsigned i = bit_index(bit);
    if (!UG_BROKEN(core, UG_BREAK_FAULT_COUNT) || !(core->faults & bit)) {
        core->fault_counts[i]++;
    }
    core->faults |= bit;
    ug_post_event(core, UG_EV_FAULT, (uint8_t)i, detail, value);
}

/* ---- status ------------------------------------------------------------------------------------------- */
void ug_core_status(const ug_core *core, ug_status *out) {
    memset(out, 0, sizeof *out);
    out->enabled = core->state != UG_OFF;
    out->playback = core->state;
    out->loop = core->loop_mode;
    out->session_version = core->session;
    out->faults = core->faults;
    out->buffered = core->buf_count;
    bool stream = core->rate != 0u && core->state != UG_OFF;
    out->stream_rate_hz = stream ? core->rate : 0u;
    out->expected_index = stream && core->have_expected ? core->expected : 0u;
    out->carrier_hz = core->carrier_hz;
    out->drive = core->drive;
    out->measured_um_pp = core->measured_um_pp;
    out->frames_ok = core->frames_ok;
    out->crc_errors = core->crc_errors;
    out->framing_errors = core->framing_errors;
    out->setpoints = core->setpoints;
    out->lost_setpoints = core->lost;
    out->late_setpoints = core->late;
    out->discarded_setpoints = core->discarded;
    out->overrun_setpoints = core->overrun;
    memcpy(out->fault_counts, core->fault_counts, sizeof out->fault_counts);
    out->naks = core->naks;
    out->rx_overflows = core->rx_overflows;
    out->tx_dropped = core->tx_dropped;
    out->events_dropped = core->events_dropped;
    out->now_ms = core->now_ms;
    out->next_telemetry_ms = core->telemetry_due ? core->now_ms : core->telemetry_due_ms;
    out->samples = core->samples;
    out->stage_hot = core->stage_hot;
    out->lost_ms = core->lost_ms;
}
