/*
 * ug_commands.c - frames from the host: the receive ring, each frame's checks in docs/protocol.md's order
 * (type, support, length, values: the first that fails is NAKed), each command's effect, and the main
 * loop's poll, which handles frames and sends what the tick made due.
 */
#include <math.h>

#include "ug_internal.h"

/* ---- frames from the host ------------------------------------------------------------------------- */
void ug_core_uart_rx(ug_core *core, const uint8_t *data, size_t n) {
    uint16_t head = atomic_load_explicit(&core->rx_head, memory_order_relaxed); /* ours: the producer's */
    uint16_t tail = atomic_load_explicit(&core->rx_tail, memory_order_acquire); /* the room the consumer freed */
    for (size_t i = 0; i < n; i++) {
        uint16_t next = (uint16_t)((head + 1u) & (UG_RX_RING - 1u));
        if (next == tail) {
            tail = atomic_load_explicit(&core->rx_tail, memory_order_acquire);
            if (next == tail) {
                core->rx_overflows++;
                continue;
            }
        }
        core->rx[head] = data[i];
        head = next;
    }
    atomic_store_explicit(&core->rx_head, head, memory_order_release); /* the bytes before the index */
}

size_t ug_core_rx_room(const ug_core *core) {
    uint16_t head = atomic_load_explicit(&core->rx_head, memory_order_acquire);
    uint16_t tail = atomic_load_explicit(&core->rx_tail, memory_order_acquire);
    return (size_t)(UG_RX_RING - 1u - ((head - tail) & (UG_RX_RING - 1u)));
}

static bool known(uint8_t type) {
    return type == UG_HELLO || type == UG_SET_CARRIER || type == UG_ENABLE || type == UG_SETPOINTS ||
           type == UG_HEARTBEAT || type == UG_CLEAR_FAULTS || type == UG_SET_LOOP || type == UG_SETPOINTS_FORCE ||
           type == UG_CLOCK || type == UG_SIM_FAULT;
}

static bool supported(const ug_core *core, uint8_t type) {
    if (type == UG_SIM_FAULT) {
        return core->config.sim_faults != 0u;
    }
    if (type == UG_SET_LOOP) {
        return core->session >= 3u && (core->config.features & UG_FEATURE_AMPLITUDE_LOOP);
    }
    if (type == UG_SETPOINTS_FORCE) {
        return core->session >= 3u && (core->config.features & UG_FEATURE_FORCE_CORRECTION);
    }
    if (type == UG_CLOCK) { /* the sensor clock: only a device with sensors has one */
        return core->session >= 3u && core->sensor_decimation != 0u;
    }
    return true;
}

static bool length_ok(uint8_t type, const uint8_t *p, size_t n) {
    switch (type) {
    case UG_HELLO: case UG_ENABLE: case UG_SET_LOOP: return n == 1u;
    case UG_SET_CARRIER: return n == 4u;
    case UG_HEARTBEAT: case UG_CLOCK: return n == 0u;
    case UG_CLEAR_FAULTS: return n == 2u;
    case UG_SIM_FAULT: return n == 3u;
    case UG_SETPOINTS: return n >= 10u && n == 10u + 2u * (size_t)ug_get_u16(p + 8);
    case UG_SETPOINTS_FORCE:
        return n >= UG_SETPOINTS_FORCE_HEADER_SIZE && n == UG_SETPOINTS_FORCE_HEADER_SIZE + 2u * (size_t)ug_get_u16(p + 8);
    default: return false;
    }
}

/* the value checks the R-NAK-ORDER break makes before the length checks */
static bool early_value_refusal(const ug_core *core, uint8_t type, const uint8_t *p, size_t n) {
    if (type == UG_ENABLE && n >= 1u) {
        return p[0] > 1u;
    }
    if ((type == UG_SETPOINTS || type == UG_SETPOINTS_FORCE) && n >= 10u) {
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

/* SETPOINTS_FORCE's reference (force_n, exponent, limit code after the count): within range? */
static bool force_reference_ok(const uint8_t *p) {
    float force_n = ug_get_f32(p + 10);
    float exponent = ug_get_f32(p + 14);
    return isfinite(force_n) && force_n > 0.0f && force_n <= UG_MAX_REFERENCE_FORCE_N && isfinite(exponent) &&
           exponent >= -UG_MAX_FORCE_EXPONENT && exponent <= UG_MAX_FORCE_EXPONENT;
}

/* SETPOINTS and SETPOINTS_FORCE (the same stream; the latter's values carry a force reference) */
static void setpoints(ug_core *core, uint8_t type, uint16_t seq, const uint8_t *p) {
    uint32_t first = ug_get_u32(p);
    uint32_t rate = ug_get_u32(p + 4);
    uint16_t count = ug_get_u16(p + 8);
    bool force = type == UG_SETPOINTS_FORCE;
    const uint8_t *codes = p + (force ? UG_SETPOINTS_FORCE_HEADER_SIZE : UG_SETPOINTS_HEADER_SIZE);
    if (count == 0u || count > UG_MAX_SETPOINTS_PER_FRAME || rate < core->config.min_setpoint_rate_hz ||
        rate > core->config.max_setpoint_rate_hz || (core->state != UG_OFF && core->rate != 0u && rate != core->rate) ||
        (force && !force_reference_ok(p))) {
        ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
        return;
    }
    if (core->state == UG_OFF) {
        core->discarded += count;
        if (UG_BROKEN(core, UG_BREAK_DISCARD)) { /* "buffers them and plays them after ENABLE 1" */
            if (core->rate == 0u || core->buf_count == 0u) {
                ug_set_rate(core, rate);
            }
            uint16_t room = core->capacity > core->buf_count ? (uint16_t)(core->capacity - core->buf_count) : 0u;
            ug_buffer_push(core, codes, first, count < room ? count : room);
        }
        return;
    }
    if (core->rate == 0u) {
        ug_set_rate(core, rate);
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
    if (put > 0u) {
        uint32_t at = core->popped + core->buf_count; /* the ordinal of the first value pushed */
        if (force) {
            ug_force_mark(core, at, ug_get_f32(p + 10), ug_get_f32(p + 14),
                          (float)ug_get_u16(p + 18) * (1.0f / (float)UG_SETPOINT_SCALE));
        } else {
            ug_force_mark(core, at, 1.0f, 0.0f, 1.0f);
        }
    }
    ug_buffer_push(core, codes + 2u * late, first + late, put);
    core->setpoints += UG_BROKEN(core, UG_BREAK_OVERRUN) ? kept : put;
    if (over > 0u) {
        if (!UG_BROKEN(core, UG_BREAK_OVERRUN)) {
            core->overrun += over;
        }
        ug_raise_fault(core, UG_FAULT_OVERRUN, 0, 0.0f);
    }
    core->last_setpoints_ms = core->now_ms;
    if (!core->streaming) {
        core->streaming = 1;
        ug_post_event(core, UG_EV_STREAM_STARTED, 0, 0, (float)core->rate);
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

/* CLOCK: the sensor clock now (the samples the core has taken and those the ADC took since: ug_port.h), in sensor
   samples and 1/65536 of one, numbered as SENSORS' first_sample; answered at once (inside the frame's section: two
   divisions and an 8-byte copy) */
static void clock_reply(ug_core *core, uint16_t seq) {
    uint8_t payload[UG_CLOCK_REPLY_SIZE];
    const uint32_t decimation = core->sensor_decimation; /* drive samples a sensor sample (1..1000: config_ok) */
    uint32_t since = ug_port_samples_since_block(core->port);
    if (since > core->config.sample_rate_hz) { /* a port's bug: no more than a second (the sums below stay in u32) */
        since = core->config.sample_rate_hz;
    }
    if (UG_BROKEN(core, UG_BREAK_CLOCK)) { /* "states its clock 10 ms behind" */
        since = 0u;
    }
    uint32_t taken = core->sensor_count_in + since;
    uint32_t sample = core->sensor_next + taken / decimation;
    if (UG_BROKEN(core, UG_BREAK_CLOCK)) {
        sample -= core->config.sensor_rate_hz / 100u;
    }
    ug_put_u16(payload, seq);
    ug_put_u32(payload + 2, sample);
    ug_put_u16(payload + 6, (uint16_t)(((taken % decimation) << 16) / decimation));
    ug_send(core, UG_CLOCK_REPLY, payload, sizeof payload);
}

/* one valid frame, in a critical section; returns a SIM_FAULT transport request (kind << 16 | ms) or 0 */
static uint32_t handle(ug_core *core, uint8_t type, uint16_t seq, const uint8_t *p, size_t n) {
    if (!known(type)) {
        ug_nak(core, type, seq, UG_NAK_UNKNOWN_TYPE);
        return 0;
    }
    if (!supported(core, type)) {
        ug_nak(core, type, seq, UG_NAK_UNSUPPORTED);
        return 0;
    }
    if (UG_BROKEN(core, UG_BREAK_NAK_ORDER) && early_value_refusal(core, type, p, n)) {
        ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
        return 0;
    }
    if (!length_ok(type, p, n)) {
        ug_nak(core, type, seq, UG_NAK_BAD_LENGTH);
        return 0;
    }
    switch (type) {
    case UG_HELLO: {
        core->session = negotiate(core, p[0]);
        ug_post_event(core, UG_EV_HELLO, p[0], core->session, 0.0f);
        if (UG_BROKEN(core, UG_BREAK_HELLO_NO_STATE)) {
            ug_disable(core, UG_WHY_HELLO);
        }
        size_t length = ug_hello_reply(core, core->scratch_payload);
        ug_send(core, UG_HELLO_REPLY, core->scratch_payload, length);
        return 0;
    }
    case UG_SET_CARRIER: {
        float hz = ug_get_f32(p);
        bool in_range = isfinite(hz) && hz >= core->config.carrier_min_hz && hz <= core->config.carrier_max_hz;
        if (!in_range) {
            if (UG_BROKEN(core, UG_BREAK_NAK_NO_EFFECT) && isfinite(hz) && hz > 0.0f) {
                ug_dds_set(core, hz);
            }
            ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (UG_BROKEN(core, UG_BREAK_CARRIER) && core->state != UG_OFF) {
            ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        ug_dds_set(core, hz);
        ug_post_event(core, UG_EV_CARRIER, 0, 0, hz);
        ug_ack(core, seq);
        return 0;
    }
    case UG_ENABLE:
        if (p[0] > 1u) {
            ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (p[0] == 1u) {
            if (core->stage_hot) {
                ug_nak(core, type, seq, UG_NAK_INTERNAL);
                return 0;
            }
            if (core->state == UG_OFF) {
                ug_enable(core);
            } else if (UG_BROKEN(core, UG_BREAK_ENABLE)) { /* "ENABLE 1 while enabled starts a new stream" */
                ug_forget_stream(core);
                ug_stop_stream(core);
                core->state = UG_PREFILL;
            }
        } else if (core->state != UG_OFF) {
            ug_disable(core, UG_WHY_HOST);
        }
        if (!UG_BROKEN(core, UG_BREAK_ACK)) {
            ug_ack(core, seq);
        }
        return 0;
    case UG_SETPOINTS:
    case UG_SETPOINTS_FORCE:
        setpoints(core, type, seq, p);
        return 0;
    case UG_HEARTBEAT:
        return 0;
    case UG_CLOCK:
        clock_reply(core, seq);
        return 0;
    case UG_CLEAR_FAULTS:
        clear_faults(core, ug_get_u16(p));
        ug_ack(core, seq);
        return 0;
    case UG_SET_LOOP:
        if (p[0] > 1u || (core->state != UG_OFF && !UG_BROKEN(core, UG_BREAK_LOOP))) {
            ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        if (core->loop_mode != p[0]) {
            core->loop_mode = p[0];
            ug_loop_reset(core);
        }
        ug_post_event(core, UG_EV_LOOP, p[0], 0, 0.0f);
        ug_ack(core, seq);
        return 0;
    default: { /* UG_SIM_FAULT */
        uint8_t kind = p[0];
        uint16_t ms = ug_get_u16(p + 1);
        if (kind < UG_SIM_DROP || kind > UG_SIM_OVERHEAT || ms > UG_MAX_SIM_FAULT_MS) {
            ug_nak(core, type, seq, UG_NAK_BAD_VALUE);
            return 0;
        }
        ug_ack(core, seq);
        ug_post_event(core, UG_EV_SIM_FAULT, kind, ms, 0.0f);
        if (kind == UG_SIM_OVERHEAT) {
            core->stage_hot = ms > 0u;
            core->hot_until_ms = core->now_ms + ms;
            ug_overheat(core);
            return 0;
        }
        return ((uint32_t)kind << 16) | ms;
    }
    }
}

/* A SETPOINTS frame's codes copied into the buffer's free room before the frame's critical section, so that the
   section only commits them (ug_buffer_push). The room is read under a short lock; the block interrupt only ever
   shrinks the used part (pops) or empties it (a clear, which bumps buf_epoch): the room stays free meanwhile. */
static void stage_setpoints(ug_core *core, uint8_t type, const uint8_t *p, size_t n) {
    size_t header = type == UG_SETPOINTS_FORCE ? UG_SETPOINTS_FORCE_HEADER_SIZE : UG_SETPOINTS_HEADER_SIZE;
    core->staged_n = 0;
    if ((type != UG_SETPOINTS && type != UG_SETPOINTS_FORCE) || !length_ok(type, p, n)) {
        return;
    }
    uint16_t count = ug_get_u16(p + 8);
    if (count == 0u || count > UG_MAX_SETPOINTS_PER_FRAME) {
        return;
    }
    ug_port_critical_enter(core->port);
    uint16_t at = (uint16_t)((core->buf_head + core->buf_count) % UG_BUFFER_CAPACITY);
    uint16_t room = (uint16_t)(UG_BUFFER_CAPACITY - core->buf_count);
    uint32_t epoch = core->buf_epoch;
    ug_port_critical_exit(core->port);
    uint16_t put = count < room ? count : room;
    const uint8_t *codes = p + header;
    uint16_t to = at;
    for (uint16_t i = 0; i < put; i++) {
        core->buf[to] = ug_get_u16(codes + 2u * i);
        to = (uint16_t)(to + 1u == UG_BUFFER_CAPACITY ? 0u : to + 1u);
    }
    core->staged_codes = codes;
    core->staged_at = at;
    core->staged_n = put;
    core->staged_epoch = epoch;
}

static void take_frame(ug_core *core) {
    const uint8_t *body = core->decoder.body;
    size_t length = core->decoder.length;
    uint32_t crc = ug_get_u32(body + length - 4u);
    bool valid = ug_crc32(body, length - 4u) == crc;
    core->staged_n = 0; /* whatever was staged for an earlier frame (the decoder reuses its body) is forgotten */
    if (valid) {
        stage_setpoints(core, body[0], body + 3, length - 7u);
    }
    ug_port_critical_enter(core->port);
    core->outbox_deferring = 1;
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
    core->outbox_deferring = 0;
    ug_port_critical_exit(core->port);
    ug_outbox_flush(core); /* the reply's CRC and COBS, with the block interrupt free to run */
    if (request != 0u) {
        ug_port_sim_fault(core->port, (uint8_t)(request >> 16), (uint16_t)request);
    }
}

void ug_core_poll(ug_core *core) {
    uint16_t max_encoded = (uint16_t)(UG_BROKEN(core, UG_BREAK_FRAMING) ? UG_MAX_BODY : UG_MAX_ENCODED);
    uint16_t tail = atomic_load_explicit(&core->rx_tail, memory_order_relaxed); /* ours: the consumer's */
    while (tail != atomic_load_explicit(&core->rx_head, memory_order_acquire)) {
        uint8_t byte = core->rx[tail];
        tail = (uint16_t)((tail + 1u) & (UG_RX_RING - 1u));
        atomic_store_explicit(&core->rx_tail, tail, memory_order_release); /* the byte read before its room is freed */
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
        ug_port_critical_enter(core->port); /* a copy of the state into the payload: ~90 bytes */
        core->telemetry_due = 0;
        size_t n = ug_telemetry_payload(core, core->scratch_payload);
        ug_port_critical_exit(core->port);
        ug_send(core, UG_TELEMETRY, core->scratch_payload, n); /* CRC, COBS, ring: outside the lock */
    }
    if (core->sensors_due) {
        uint32_t first = 0;
        uint8_t count = 0;
        ug_port_critical_enter(core->port); /* the rings swapped: a few instructions */
        core->sensors_due = 0;
        if (core->session >= 3u) {
            count = ug_sensors_swap(core, &first);
        } else {
            core->sensor_pending = 0; /* a v2 host gets none */
        }
        ug_port_critical_exit(core->port);
        if (count > 0u) {
            ug_send_sensors(core, count, first); /* up to a 969-byte frame, encoded with the blocks running */
        }
    }
}
