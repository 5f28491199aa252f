/*
 * ug_core.c - the protocol state machine of docs/protocol.md (version 3, and version 2's layouts),
 * the jitter buffer and its playback, the watchdog, faults and counters, telemetry and SENSORS.
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
    "R-FAULT-LATCH", "R-FAULT-COUNT", "R-CLEAR-FAULTS", "R-LOOP",
};

const char *ug_break_rule(unsigned which) { return which < UG_BREAKS ? rule_names[which] : NULL; }

#define STREAM_GAP_MS 50u /* no SETPOINTS for this long: the stream has stopped (an event, not a fault) */
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
    if ((c->features & ~UG_FEATURE_AMPLITUDE_LOOP) ||
        ((c->features & UG_FEATURE_AMPLITUDE_LOOP) && !(c->sensors & UG_SENSOR_AMPLITUDE))) {
        return false;
    }
    if (c->max_version < UG_LOWEST_VERSION || c->max_version > UG_PROTOCOL_VERSION || c->sim_faults > 1u) {
        return false;
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
    core->telemetry_period_ms = 1000u / UG_TELEMETRY_HZ;
    core->session = config->max_version;
    core->state = UG_OFF;
    core->over_armed = 1u;
    core->telemetry_due_ms = 0u; /* the first TELEMETRY at the first tick, the next one a period later */
    core->sensor_decimation = config->sensors ? config->sample_rate_hz / config->sensor_rate_hz : 0u;
    ug_decoder_reset(&core->decoder);
    ug_dds_set(core, config->carrier_hz);
    ug_loop_reset(core);
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
static void event(ug_core *core, uint8_t kind, uint8_t a, uint16_t b, float value) {
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

static void raise_fault(ug_core *core, uint16_t bit, uint16_t detail, float value) {
    unsigned i = bit_index(bit);
    if (!UG_BROKEN(core, UG_BREAK_FAULT_COUNT) || !(core->faults & bit)) {
        core->fault_counts[i]++;
    }
    core->faults |= bit;
    event(core, UG_EV_FAULT, (uint8_t)i, detail, value);
}

/* ---- the buffer ------------------------------------------------------------------------------------ */
static void buffer_clear(ug_core *core) {
    core->buf_head = 0;
    core->buf_count = 0;
    core->jump_count = 0;
}

static uint16_t buffer_pop(ug_core *core) {
    uint16_t value = core->buf[core->buf_head];
    core->buf_head = (uint16_t)((core->buf_head + 1u) % UG_BUFFER_CAPACITY);
    core->buf_count--;
    while (core->jump_count > 0u && core->jumps[core->jump_head].at == core->popped) {
        core->next_pop_index += core->jumps[core->jump_head].jump;
        core->jump_head = (uint8_t)((core->jump_head + 1u) & (UG_JUMPS - 1u));
        core->jump_count--;
    }
    core->play_index = core->next_pop_index++;
    core->popped++;
    return value;
}

/* values of a frame, from stream index `first`, into the buffer (the caller checked the room) */
static void buffer_push(ug_core *core, const uint8_t *codes, uint32_t first, uint16_t n) {
    if (n == 0u) {
        return;
    }
    if (core->buf_count == 0u) {
        core->next_pop_index = first;
        core->jump_count = 0;
    } else if (first != core->tail_index && core->jump_count < UG_JUMPS) {
        unsigned slot = (core->jump_head + core->jump_count) & (UG_JUMPS - 1u);
        core->jumps[slot].at = core->popped + core->buf_count;
        core->jumps[slot].jump = first - core->tail_index;
        core->jump_count++;
    }
    uint16_t at = (uint16_t)((core->buf_head + core->buf_count) % UG_BUFFER_CAPACITY);
    for (uint16_t i = 0; i < n; i++) {
        core->buf[at] = ug_get_u16(codes + 2u * i);
        at = (uint16_t)(at + 1u == UG_BUFFER_CAPACITY ? 0u : at + 1u);
    }
    core->buf_count = (uint16_t)(core->buf_count + n);
    core->tail_index = first + n;
}

/* ---- output state ------------------------------------------------------------------------------------ */
static void stop_stream(ug_core *core) {
    if (core->streaming) {
        core->streaming = 0;
        event(core, UG_EV_STREAM_STOPPED, 0, 0, 0.0f);
    }
}

static void forget_stream(ug_core *core) {
    buffer_clear(core);
    core->have_expected = 0;
    if (!UG_BROKEN(core, UG_BREAK_RATE)) {
        core->rate = 0;
    }
}

static void disable(ug_core *core, uint8_t why) {
    bool was = core->state != UG_OFF;
    core->state = UG_OFF;
    forget_stream(core);
    core->drive = core->current = core->next = core->hold = 0.0f;
    core->ramp_left = 0;
    stop_stream(core);
    ug_loop_reset(core);
    if (was) {
        event(core, UG_EV_DISABLED, why, 0, 0.0f);
    }
}

static void enable(ug_core *core) {
    core->state = UG_PREFILL;
    if (!UG_BROKEN(core, UG_BREAK_DISCARD)) {
        forget_stream(core);
    }
    core->have_expected = 0;
    core->last_frame_ms = core->now_ms;
    core->watchdog_fired = 0;
    core->drive = core->current = core->next = core->hold = 0.0f;
    ug_loop_reset(core);
    event(core, UG_EV_ENABLED, 0, 0, 0.0f);
}

static void set_rate(ug_core *core, uint32_t rate) {
    core->rate = rate;
    core->step = ((uint64_t)rate << 32) / core->config.sample_rate_hz;
    uint32_t prefill = (UG_PREFILL_MS * rate + 999u) / 1000u;
    core->prefill = (uint16_t)(UG_BROKEN(core, UG_BREAK_PREFILL) ? 1u : prefill);
    uint32_t capacity = (uint32_t)core->config.buffer_ms * rate / 1000u;
    core->capacity = (uint16_t)(capacity > UG_BUFFER_CAPACITY ? UG_BUFFER_CAPACITY : capacity);
}

static void overheat(ug_core *core) {
    raise_fault(core, UG_FAULT_OVERHEAT, 0, 0.0f);
    disable(core, UG_WHY_OVERHEAT);
}

void ug_core_set_stage_hot(ug_core *core, bool hot) {
    ug_port_critical_enter(core->port);
    if (hot && !core->stage_hot) {
        core->stage_hot = 1;
        core->hot_until_ms = 0;
        overheat(core);
    } else if (!hot) {
        core->stage_hot = 0;
    }
    ug_port_critical_exit(core->port);
}

/* ---- frames to the host ---------------------------------------------------------------------------- */
static uint16_t tx_used(const ug_core *core) { return (uint16_t)((core->tx_head - core->tx_tail) & (UG_TX_RING - 1u)); }

static void send(ug_core *core, uint8_t type, const uint8_t *payload, size_t n) {
    uint8_t *body = core->scratch_body;
    body[0] = type;
    ug_put_u16(body + 1, core->seq);
    if (n > 0u) {
        memcpy(body + 3, payload, n);
    }
    ug_put_u32(body + 3 + n, ug_crc32(body, 3 + n));
    size_t length = ug_cobs_encode(body, n + 7u, core->frame);
    core->frame[length++] = 0;
    if (length > (size_t)(UG_TX_RING - 1u - tx_used(core))) {
        core->tx_dropped++;
        return;
    }
    uint16_t head = core->tx_head;
    for (size_t i = 0; i < length; i++) {
        core->tx[head] = core->frame[i];
        head = (uint16_t)((head + 1u) & (UG_TX_RING - 1u));
    }
    core->tx_head = head;
    if (!(UG_BROKEN(core, UG_BREAK_DEVICE_SEQ) && (type == UG_ACK || type == UG_NAK))) {
        core->seq++; /* broken: "its ACK and NAK frames take no seq of their own" */
    }
    ug_port_tx_ready(core->port);
}

size_t ug_core_uart_tx(ug_core *core, uint8_t *out, size_t max) {
    size_t n = 0;
    uint16_t tail = core->tx_tail;
    while (n < max && tail != core->tx_head) {
        out[n++] = core->tx[tail];
        tail = (uint16_t)((tail + 1u) & (UG_TX_RING - 1u));
    }
    core->tx_tail = tail;
    return n;
}

static void ack(ug_core *core, uint16_t seq) {
    uint8_t payload[2];
    ug_put_u16(payload, UG_BROKEN(core, UG_BREAK_SEQ_ECHO) ? core->seq : seq);
    send(core, UG_ACK, payload, sizeof payload);
}

static void nak(ug_core *core, uint8_t type, uint16_t seq, uint8_t reason) {
    uint8_t payload[3];
    core->naks++;
    raise_fault(core, UG_FAULT_BAD_COMMAND, (uint16_t)((type << 8) | reason), 0.0f);
    ug_put_u16(payload, UG_BROKEN(core, UG_BREAK_SEQ_ECHO) ? core->seq : seq);
    payload[2] = reason;
    send(core, UG_NAK, payload, sizeof payload);
}

static size_t hello_reply(const ug_core *core, uint8_t *p) {
    const ug_config *c = &core->config;
    p[0] = core->session;
    ug_put_f32(p + 1, c->resonance_hz);
    ug_put_f32(p + 5, c->full_scale_um_pp);
    ug_put_f32(p + 9, c->max_amplitude_um_pp);
    ug_put_u32(p + 13, c->min_setpoint_rate_hz);
    ug_put_u32(p + 17, c->max_setpoint_rate_hz);
    ug_put_f32(p + 21, c->carrier_min_hz);
    ug_put_f32(p + 25, c->carrier_max_hz);
    ug_put_u16(p + 29, c->watchdog_ms);
    ug_put_u16(p + 31, c->buffer_ms);
    size_t n = UG_HELLO_REPLY_V2_SIZE;
    if (core->session >= 3u) {
        ug_put_f32(p + 33, c->max_drive_um_pp);
        p[37] = c->sensors;
        ug_put_u16(p + 38, c->sensor_rate_hz);
        p[40] = c->features;
        n = UG_HELLO_REPLY_V3_SIZE;
    }
    size_t name = strlen(c->name); /* NUL-terminated within 65 bytes (config_ok) */
    memcpy(p + n, c->name, name);
    return n + name;
}

static uint16_t drive_code(float drive) {
    float code = drive * (float)UG_SETPOINT_SCALE + 0.5f;
    return (uint16_t)(code <= 0.0f ? 0.0f : (code >= 65535.0f ? 65535.0f : code));
}

static void send_telemetry(ug_core *core) {
    uint8_t *p = core->scratch_payload;
    ug_put_f32(p, core->measured_um_pp);
    ug_put_f32(p + 4, core->carrier_hz);
    ug_put_u16(p + 8, core->faults);
    p[10] = core->state != UG_OFF;
    const uint32_t counters[7] = {core->frames_ok, core->crc_errors, core->framing_errors, core->setpoints,
                                  core->lost, core->late, core->discarded};
    for (unsigned i = 0; i < 7u; i++) {
        ug_put_u32(p + 11 + 4 * i, counters[i]);
    }
    for (unsigned i = 0; i < UG_FAULT_BITS; i++) {
        ug_put_u32(p + 39 + 4 * i, core->fault_counts[i]);
    }
    size_t n = UG_TELEMETRY_V2_SIZE;
    if (core->session >= 3u) {
        bool stream = core->rate != 0u && core->state != UG_OFF;
        ug_put_u32(p + 71, core->overrun);
        ug_put_u32(p + 75, stream && core->have_expected ? core->expected : 0u);
        ug_put_u32(p + 79, stream ? core->rate : 0u);
        ug_put_u16(p + 83, core->buf_count);
        ug_put_u16(p + 85, drive_code(core->drive));
        p[87] = core->state;
        p[88] = core->loop_mode;
        n = UG_TELEMETRY_V3_SIZE;
    }
    if (UG_BROKEN(core, UG_BREAK_FAULT_LATCH)) {
        core->faults = 0; /* "bits clear themselves once telemetry has reported them" */
    }
    send(core, UG_TELEMETRY, p, n);
}

static void send_sensors(ug_core *core) {
    uint8_t *p = core->scratch_payload;
    uint8_t count = core->sensor_pending;
    if (count == 0u) {
        return;
    }
    ug_put_u32(p, core->sensor_next - count);
    ug_put_u32(p + 4, core->sensor_ring[0].index);
    p[8] = count;
    for (unsigned i = 0; i < count; i++) {
        for (unsigned k = 0; k < 3u; k++) {
            ug_put_f32(p + UG_SENSORS_HEADER_SIZE + UG_SENSOR_SAMPLE_SIZE * i + 4u * k, core->sensor_ring[i].value[k]);
        }
    }
    core->sensor_pending = 0;
    if (UG_BROKEN(core, UG_BREAK_SENSORS)) {
        core->sensor_next++; /* "skips a sample between frames" */
    }
    send(core, UG_SENSORS, p, UG_SENSORS_HEADER_SIZE + UG_SENSOR_SAMPLE_SIZE * (size_t)count);
}

/* ---- frames from the host ------------------------------------------------------------------------- */
void ug_core_uart_rx(ug_core *core, const uint8_t *data, size_t n) {
    uint16_t head = core->rx_head;
    for (size_t i = 0; i < n; i++) {
        uint16_t next = (uint16_t)((head + 1u) & (UG_RX_RING - 1u));
        if (next == core->rx_tail) {
            core->rx_overflows++;
            continue;
        }
        core->rx[head] = data[i];
        head = next;
    }
    core->rx_head = head;
}

size_t ug_core_rx_room(const ug_core *core) {
    return (size_t)(UG_RX_RING - 1u - ((core->rx_head - core->rx_tail) & (UG_RX_RING - 1u)));
}

static bool known(uint8_t type) {
    return type == UG_HELLO || type == UG_SET_CARRIER || type == UG_ENABLE || type == UG_SETPOINTS ||
           type == UG_HEARTBEAT || type == UG_CLEAR_FAULTS || type == UG_SET_LOOP || type == UG_SIM_FAULT;
}

static bool supported(const ug_core *core, uint8_t type) {
    if (type == UG_SIM_FAULT) {
        return core->config.sim_faults != 0u;
    }
    if (type == UG_SET_LOOP) {
        return core->session >= 3u && (core->config.features & UG_FEATURE_AMPLITUDE_LOOP);
    }
    return true;
}

static bool length_ok(uint8_t type, const uint8_t *p, size_t n) {
    switch (type) {
    case UG_HELLO: case UG_ENABLE: case UG_SET_LOOP: return n == 1u;
    case UG_SET_CARRIER: return n == 4u;
    case UG_HEARTBEAT: return n == 0u;
    case UG_CLEAR_FAULTS: return n == 2u;
    case UG_SIM_FAULT: return n == 3u;
    case UG_SETPOINTS: return n >= 10u && n == 10u + 2u * (size_t)ug_get_u16(p + 8);
    default: return false;
    }
}

/* the value checks the R-NAK-ORDER break makes before the length checks */
static bool early_value_refusal(const ug_core *core, uint8_t type, const uint8_t *p, size_t n) {
    if (type == UG_ENABLE && n >= 1u) {
        return p[0] > 1u;
    }
    if (type == UG_SETPOINTS && n >= 10u) {
        uint32_t rate = ug_get_u32(p + 4);
        uint16_t count = ug_get_u16(p + 8);
        return count == 0u || count > UG_MAX_SETPOINTS_PER_FRAME || rate < core->config.min_setpoint_rate_hz ||
               rate > core->config.max_setpoint_rate_hz;
    }
    return false;
}

static uint8_t negotiate(const ug_core *core, uint8_t host) {
    uint8_t highest = core->config.max_version;
    if (host >= highest || (UG_BROKEN(core, UG_BREAK_VERSION) && host == 2u)) { /* broken: "answers v3 to a v2 host" */
        return highest;
    }
    return host >= UG_LOWEST_VERSION ? host : UG_LOWEST_VERSION;
}

static void setpoints(ug_core *core, uint8_t type, uint16_t seq, const uint8_t *p) {
    uint32_t first = ug_get_u32(p);
    uint32_t rate = ug_get_u32(p + 4);
    uint16_t count = ug_get_u16(p + 8);
    const uint8_t *codes = p + 10;
    if (count == 0u || count > UG_MAX_SETPOINTS_PER_FRAME || rate < core->config.min_setpoint_rate_hz ||
        rate > core->config.max_setpoint_rate_hz || (core->state != UG_OFF && core->rate != 0u && rate != core->rate)) {
        nak(core, type, seq, UG_NAK_BAD_VALUE);
        return;
    }
    if (core->state == UG_OFF) {
        core->discarded += count;
        if (UG_BROKEN(core, UG_BREAK_DISCARD)) { /* "buffers them and plays them after ENABLE 1" */
            if (core->rate == 0u || core->buf_count == 0u) {
                set_rate(core, rate);
            }
            uint16_t room = core->capacity > core->buf_count ? (uint16_t)(core->capacity - core->buf_count) : 0u;
            buffer_push(core, codes, first, count < room ? count : room);
        }
        return;
    }
    if (core->rate == 0u) {
        set_rate(core, rate);
    }
    uint16_t late = 0;
    if (!core->have_expected) {
        core->have_expected = 1;
    } else {
        uint32_t d = first - core->expected;
        if (d != 0u && d < 0x80000000u) {
            core->lost += d;
        } else if (d >= 0x80000000u) {
            uint32_t behind = 0u - d;
            late = (uint16_t)(behind < count ? behind : count);
            core->late += late;
        }
    }
    uint16_t kept = (uint16_t)(count - late);
    if (UG_BROKEN(core, UG_BREAK_EXPECTED)) {
        core->expected = first + kept; /* v2's formula: moves backwards after a late frame */
    } else if (kept > 0u) {
        core->expected = first + count;
    }
    uint16_t room = core->capacity > core->buf_count ? (uint16_t)(core->capacity - core->buf_count) : 0u;
    uint16_t put = kept < room ? kept : room;
    uint16_t over = (uint16_t)(kept - put);
    buffer_push(core, codes + 2u * late, first + late, put);
    core->setpoints += UG_BROKEN(core, UG_BREAK_OVERRUN) ? kept : put;
    if (over > 0u) {
        if (!UG_BROKEN(core, UG_BREAK_OVERRUN)) {
            core->overrun += over;
        }
        raise_fault(core, UG_FAULT_OVERRUN, 0, 0.0f);
    }
    core->last_setpoints_ms = core->now_ms;
    if (!core->streaming) {
        core->streaming = 1;
        event(core, UG_EV_STREAM_STARTED, 0, 0, (float)core->rate);
    }
}

static void clear_faults(ug_core *core, uint16_t mask) {
    if (UG_BROKEN(core, UG_BREAK_CLEAR_FAULTS)) {
        return;
    }
    core->faults = (uint16_t)(core->faults & ~mask);
    if (core->stage_hot) {
        core->faults |= UG_FAULT_OVERHEAT; /* the condition persists: set again, not counted */
    }
    if (core->measured_um_pp > core->config.max_amplitude_um_pp) {
        core->faults |= UG_FAULT_OVER_LIMIT;
    }
}

/* one valid frame, in a critical section; returns a SIM_FAULT transport request (kind << 16 | ms) or 0 */
static uint32_t handle(ug_core *core, uint8_t type, uint16_t seq, const uint8_t *p, size_t n) {
    if (!known(type)) {
        nak(core, type, seq, UG_NAK_UNKNOWN_TYPE);
        return 0;
    }
    if (!supported(core, type)) {
        nak(core, type, seq, UG_NAK_UNSUPPORTED);
        return 0;
    }
    if (UG_BROKEN(core, UG_BREAK_NAK_ORDER) && early_value_refusal(core, type, p, n)) {
        nak(core, type, seq, UG_NAK_BAD_VALUE);
        return 0;
    }
    if (!length_ok(type, p, n)) {
        nak(core, type, seq, UG_NAK_BAD_LENGTH);
        return 0;
    }
    switch (type) {
    case UG_HELLO: {
        core->session = negotiate(core, p[0]);
        event(core, UG_EV_HELLO, p[0], core->session, 0.0f);
        if (UG_BROKEN(core, UG_BREAK_HELLO_NO_STATE)) {
            disable(core, UG_WHY_HELLO);
        }
        size_t length = hello_reply(core, core->scratch_payload);
        send(core, UG_HELLO_REPLY, core->scratch_payload, length);
        return 0;
    }
    case UG_SET_CARRIER: {
        float hz = ug_get_f32(p);
        bool in_range = isfinite(hz) && hz >= core->config.carrier_min_hz && hz <= core->config.carrier_max_hz;
        if (!in_range) {
            if (UG_BROKEN(core, UG_BREAK_NAK_NO_EFFECT) && isfinite(hz) && hz > 0.0f) {
                ug_dds_set(core, hz);
            }
            nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (UG_BROKEN(core, UG_BREAK_CARRIER) && core->state != UG_OFF) {
            nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        ug_dds_set(core, hz);
        event(core, UG_EV_CARRIER, 0, 0, hz);
        ack(core, seq);
        return 0;
    }
    case UG_ENABLE:
        if (p[0] > 1u) {
            nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (p[0] == 1u) {
            if (core->stage_hot) {
                nak(core, type, seq, UG_NAK_INTERNAL);
                return 0;
            }
            if (core->state == UG_OFF) {
                enable(core);
            } else if (UG_BROKEN(core, UG_BREAK_ENABLE)) { /* "ENABLE 1 while enabled starts a new stream" */
                forget_stream(core);
                stop_stream(core);
                core->state = UG_PREFILL;
            }
        } else if (core->state != UG_OFF) {
            disable(core, UG_WHY_HOST);
        }
        if (!UG_BROKEN(core, UG_BREAK_ACK)) {
            ack(core, seq);
        }
        return 0;
    case UG_SETPOINTS:
        setpoints(core, type, seq, p);
        return 0;
    case UG_HEARTBEAT:
        return 0;
    case UG_CLEAR_FAULTS:
        clear_faults(core, ug_get_u16(p));
        ack(core, seq);
        return 0;
    case UG_SET_LOOP:
        if (p[0] > 1u || (core->state != UG_OFF && !UG_BROKEN(core, UG_BREAK_LOOP))) {
            nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (core->loop_mode != p[0]) {
            core->loop_mode = p[0];
            ug_loop_reset(core);
        }
        event(core, UG_EV_LOOP, p[0], 0, 0.0f);
        ack(core, seq);
        return 0;
    default: { /* UG_SIM_FAULT */
        uint8_t kind = p[0];
        uint16_t ms = ug_get_u16(p + 1);
        if (kind < UG_SIM_DROP || kind > UG_SIM_OVERHEAT || ms > UG_MAX_SIM_FAULT_MS) {
            nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        ack(core, seq);
        event(core, UG_EV_SIM_FAULT, kind, ms, 0.0f);
        if (kind == UG_SIM_OVERHEAT) {
            core->stage_hot = ms > 0u;
            core->hot_until_ms = core->now_ms + ms;
            overheat(core);
            return 0;
        }
        return ((uint32_t)kind << 16) | ms;
    }
    }
}

static void take_frame(ug_core *core) {
    const uint8_t *body = core->decoder.body;
    size_t length = core->decoder.length;
    uint32_t crc = ug_get_u32(body + length - 4u);
    bool valid = ug_crc32(body, length - 4u) == crc;
    ug_port_critical_enter(core->port);
    if (!valid) {
        core->crc_errors++;
    }
    uint32_t request = 0;
    if (valid || UG_BROKEN(core, UG_BREAK_CRC)) {
        core->frames_ok++;
        core->last_frame_ms = core->now_ms;
        core->watchdog_fired = 0; /* a new silence starts */
        request = handle(core, body[0], ug_get_u16(body + 1), body + 3, length - 7u);
    }
    ug_port_critical_exit(core->port);
    if (request != 0u) {
        ug_port_sim_fault(core->port, (uint8_t)(request >> 16), (uint16_t)request);
    }
}

void ug_core_poll(ug_core *core) {
    uint16_t max_encoded = (uint16_t)(UG_BROKEN(core, UG_BREAK_FRAMING) ? UG_MAX_BODY : UG_MAX_ENCODED);
    while (core->rx_tail != core->rx_head) {
        uint8_t byte = core->rx[core->rx_tail];
        core->rx_tail = (uint16_t)((core->rx_tail + 1u) & (UG_RX_RING - 1u));
        int result = ug_decoder_feed(&core->decoder, byte, max_encoded);
        if (result == UG_DECODE_FRAME) {
            take_frame(core);
        } else if (result == UG_DECODE_ERROR) {
            ug_port_critical_enter(core->port);
            core->framing_errors++;
            ug_port_critical_exit(core->port);
        }
    }
    if (core->telemetry_due) {
        ug_port_critical_enter(core->port);
        core->telemetry_due = 0;
        send_telemetry(core);
        ug_port_critical_exit(core->port);
    }
    if (core->sensors_due) {
        ug_port_critical_enter(core->port);
        core->sensors_due = 0;
        if (core->session >= 3u) {
            send_sensors(core);
        } else {
            core->sensor_pending = 0; /* a v2 host gets none */
        }
        ug_port_critical_exit(core->port);
    }
}

/* ---- time ------------------------------------------------------------------------------------------- */
static void fire_watchdog(ug_core *core) {
    core->watchdog_fired = 1;
    raise_fault(core, UG_FAULT_WATCHDOG, 0, 0.0f);
    core->ramp_from = core->drive;
    core->ramp_samples = core->config.sample_rate_hz / 1000u * UG_WATCHDOG_RAMP_MS;
    core->ramp_left = core->ramp_samples;
    buffer_clear(core); /* the stream (rate, expected) stays */
    core->state = UG_RAMP;
    stop_stream(core);
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
        raise_fault(core, UG_FAULT_UNDERRUN, 0, 0.0f);
    }
    if (UG_BROKEN(core, UG_BREAK_OVER_LIMIT) && core->measured_um_pp > core->config.max_amplitude_um_pp) {
        raise_fault(core, UG_FAULT_OVER_LIMIT, 0, core->measured_um_pp);
    }
    if (core->streaming && core->now_ms - core->last_setpoints_ms >= STREAM_GAP_MS) {
        stop_stream(core);
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

/* ---- playback: one drive sample ------------------------------------------------------------------- */
static float code_fraction(uint16_t code) { return (float)code * (1.0f / (float)UG_SETPOINT_SCALE); }

static void start_playing(ug_core *core) {
    core->current = code_fraction(buffer_pop(core));
    core->phase = 0;
    core->state = UG_PLAYING;
}

static float render_sample(ug_core *core) {
    float requested = 0.0f;
    bool playing = false;       /* a stream value or the dry hold is the target */
    bool value_playing = false; /* a stream value plays (not the hold) */
    uint32_t playing_index = core->play_index;
    switch (core->state) {
    case UG_PREFILL:
        if (core->rate != 0u && core->buf_count >= core->prefill) {
            start_playing(core);
            requested = core->current;
            playing = value_playing = true;
            playing_index = core->play_index;
        }
        break;
    case UG_PLAYING: {
        float next = core->buf_count > 0u ? code_fraction(core->buf[core->buf_head]) : core->current;
        requested = core->current + (next - core->current) * ((float)core->phase * (1.0f / 4294967296.0f));
        playing = value_playing = true;
        uint64_t phase = (uint64_t)core->phase + core->step; /* 33 bits: a stream at the drive rate steps 2^32 */
        bool due = phase > 0xFFFFFFFFu;
        core->phase = (uint32_t)phase;
        if (due) {
            if (core->buf_count > 0u) {
                core->current = code_fraction(buffer_pop(core));
            } else {
                core->state = UG_DRY;
                core->hold = core->current < core->limit_fraction ? core->current : core->limit_fraction;
                if (!UG_BROKEN(core, UG_BREAK_UNDERRUN)) {
                    raise_fault(core, UG_FAULT_UNDERRUN, 0, 0.0f);
                }
            }
        }
        break;
    }
    case UG_DRY:
        if (core->buf_count >= core->prefill) {
            start_playing(core);
            requested = core->current;
            value_playing = true;
            playing_index = core->play_index;
        } else {
            requested = core->hold;
        }
        playing = true;
        break;
    case UG_RAMP: {
        float drive = core->ramp_samples ? core->ramp_from * (float)core->ramp_left / (float)core->ramp_samples : 0.0f;
        if (core->ramp_left > 0u) {
            core->ramp_left--;
        }
        if (core->ramp_left == 0u) {
            if (core->rate != 0u && core->buf_count >= core->prefill) {
                start_playing(core);
            } else {
                core->state = UG_PREFILL;
            }
        }
        core->drive = ug_limit(core, drive);
        ug_loop_record(core, 0.0f, core->drive);
        core->hist_index[core->hist_head] = UG_NOT_PLAYING;
        return core->drive;
    }
    default:
        break;
    }
    float wanted = requested;
    if (playing && core->loop_mode == 1u) {
        wanted = ug_loop_drive(core, requested);
    } else if (!playing) {
        wanted = 0.0f;
    }
    core->drive = ug_limit(core, wanted);
    ug_loop_record(core, playing ? requested : 0.0f, core->drive);
    core->hist_index[core->hist_head] = value_playing ? playing_index : UG_NOT_PLAYING;
    return core->drive;
}

void ug_core_drive_block(ug_core *core, float *drive, size_t n) {
    for (size_t i = 0; i < n; i++) {
        drive[i] = render_sample(core);
        core->samples++;
    }
}

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
        core->sensor_ring[core->sensor_pending].value[k] =
            (core->config.sensors & bits[k]) ? core->sensor_sum[k] * scale : NAN;
    }
    core->sensor_ring[core->sensor_pending].index = core->sensor_first_index;
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
                raise_fault(core, UG_FAULT_OVER_LIMIT, 0, measured);
            }
            core->over_armed = 0;
        } else if (measured < core->rearm_um_pp) {
            core->over_armed = 1;
        }
        if (measured > core->trip_um_pp && core->state != UG_OFF) {
            raise_fault(core, UG_FAULT_TRIP, 0, measured);
            disable(core, UG_WHY_TRIP);
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
    if (n > 0u) {
        ug_loop_measured(core, n);
    }
    return cut;
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
}
