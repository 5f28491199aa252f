/* ug_tx.c - frames to the host: the transmit ring, ACK and NAK, HELLO_REPLY, TELEMETRY and SENSORS. */
#include <string.h>

#include "ug_internal.h"

/* ---- frames to the host ---------------------------------------------------------------------------- */
static uint16_t tx_used(const ug_core *core) {
    uint16_t head = atomic_load_explicit(&core->tx_head, memory_order_relaxed);
    uint16_t tail = atomic_load_explicit(&core->tx_tail, memory_order_acquire);
    return (uint16_t)((head - tail) & (UG_TX_RING - 1u));
}

static void encode_and_queue(ug_core *core, uint8_t type, const uint8_t *payload, size_t n);

void ug_send(ug_core *core, uint8_t type, const uint8_t *payload, size_t n) {
    if (core->outbox_deferring && core->outbox_count < UG_OUTBOX && n <= UG_OUTBOX_PAYLOAD) {
        /* inside a frame's critical section: keep the reply, encode it (CRC, COBS, ring) after the lock */
        unsigned slot = core->outbox_count++;
        core->outbox[slot].type = type;
        core->outbox[slot].length = (uint8_t)n;
        for (size_t i = 0; i < n; i++) {
            core->outbox[slot].payload[i] = payload[i];
        }
        return;
    }
    encode_and_queue(core, type, payload, n);
}

void ug_outbox_flush(ug_core *core) {
    for (unsigned i = 0; i < core->outbox_count; i++) {
        encode_and_queue(core, core->outbox[i].type, core->outbox[i].payload, core->outbox[i].length);
    }
    core->outbox_count = 0;
}

static void encode_and_queue(ug_core *core, uint8_t type, const uint8_t *payload, size_t n) {
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
    uint16_t head = atomic_load_explicit(&core->tx_head, memory_order_relaxed);
    for (size_t i = 0; i < length; i++) {
        core->tx[head] = core->frame[i];
        head = (uint16_t)((head + 1u) & (UG_TX_RING - 1u));
    }
    atomic_store_explicit(&core->tx_head, head, memory_order_release); /* the frame's bytes before the index */
    if (!(UG_BROKEN(core, UG_BREAK_DEVICE_SEQ) && (type == UG_ACK || type == UG_NAK))) {
        core->seq++; /* broken: "its ACK and NAK frames take no seq of their own" */
    }
    ug_port_tx_ready(core->port);
}

size_t ug_core_uart_tx(ug_core *core, uint8_t *out, size_t max) {
    size_t n = 0;
    uint16_t tail = atomic_load_explicit(&core->tx_tail, memory_order_relaxed);
    uint16_t head = atomic_load_explicit(&core->tx_head, memory_order_acquire);
    while (n < max && tail != head) {
        out[n++] = core->tx[tail];
        tail = (uint16_t)((tail + 1u) & (UG_TX_RING - 1u));
    }
    atomic_store_explicit(&core->tx_tail, tail, memory_order_release);
    return n;
}

void ug_ack(ug_core *core, uint16_t seq) {
    uint8_t payload[2];
    ug_put_u16(payload, UG_BROKEN(core, UG_BREAK_SEQ_ECHO) ? core->seq : seq);
    ug_send(core, UG_ACK, payload, sizeof payload);
}

void ug_nak(ug_core *core, uint8_t type, uint16_t seq, uint8_t reason) {
    uint8_t payload[3];
    core->naks++;
    ug_raise_fault(core, UG_FAULT_BAD_COMMAND, (uint16_t)((type << 8) | reason), 0.0f);
    ug_put_u16(payload, UG_BROKEN(core, UG_BREAK_SEQ_ECHO) ? core->seq : seq);
    payload[2] = reason;
    ug_send(core, UG_NAK, payload, sizeof payload);
}

size_t ug_hello_reply(const ug_core *core, uint8_t *p) {
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
        if (c->link_bytes_per_s != 0u) { /* what the link carries, and the plate's Q: the host fits its stream */
            p[40] = (uint8_t)(c->features | UG_FEATURE_LINK_STATED);
            ug_put_u32(p + 41, c->link_bytes_per_s);
            ug_put_f32(p + 45, c->q);
            n = UG_HELLO_REPLY_LINK_SIZE;
        }
        if (c->sensors != 0u) { /* CLOCK answered with the sensor clock: the host places its SENSORS on its own clock */
            p[40] = (uint8_t)(p[40] | UG_FEATURE_CLOCK_STATED);
        }
        if (c->reset_stated != 0u) { /* why the board last started: a host reconnecting after a reset learns why */
            p[40] = (uint8_t)(p[40] | UG_FEATURE_RESET_STATED);
            p[n] = c->reset_reason;
            ug_put_u32(p + n + 1, c->reset_detail);
            n += UG_HELLO_RESET_SIZE;
        }
    }
    size_t name = strlen(c->name); /* NUL-terminated within 65 bytes (config_ok) */
    memcpy(p + n, c->name, name);
    return n + name;
}

static uint16_t drive_code(float drive) {
    float code = drive * (float)UG_SETPOINT_SCALE + 0.5f;
    return (uint16_t)(code <= 0.0f ? 0.0f : (code >= 65535.0f ? 65535.0f : code));
}

size_t ug_telemetry_payload(ug_core *core, uint8_t *p) {
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
    return n;
}

uint8_t ug_sensors_swap(ug_core *core, uint32_t *first_number) {
    uint8_t count = core->sensor_pending;
    if (count == 0u) {
        return 0u;
    }
    *first_number = core->sensor_next - count;
    core->sensor_pending = 0;
    core->sensor_active ^= 1u; /* the block interrupt fills the other ring from now on */
    if (UG_BROKEN(core, UG_BREAK_SENSORS)) {
        core->sensor_next++; /* "skips a sample between frames" */
    }
    return count;
}

void ug_send_sensors(ug_core *core, uint8_t count, uint32_t first_number) {
    uint8_t *p = core->scratch_payload;
    const unsigned ring = core->sensor_active ^ 1u; /* the one swapped out: the block interrupt no longer writes it */
    ug_put_u32(p, first_number);
    ug_put_u32(p + 4, core->sensor_ring[ring][0].index);
    p[8] = count;
    for (unsigned i = 0; i < count; i++) {
        for (unsigned k = 0; k < 3u; k++) {
            ug_put_f32(p + UG_SENSORS_HEADER_SIZE + UG_SENSOR_SAMPLE_SIZE * i + 4u * k,
                       core->sensor_ring[ring][i].value[k]);
        }
    }
    ug_send(core, UG_SENSORS, p, UG_SENSORS_HEADER_SIZE + UG_SENSOR_SAMPLE_SIZE * (size_t)count);
}
