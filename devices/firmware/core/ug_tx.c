/* ug_tx.c - frames to the host: the transmit ring, ACK and NAK, HELLO_REPLY, TELEMETRY and SENSORS. */
#include <string.h>

#include "ug_internal.h"

/* ---- frames to the host ---------------------------------------------------------------------------- */
static uint16_t tx_used(const ug_core *core) { return (uint16_t)((core->tx_head - core->tx_tail) & (UG_TX_RING - 1u)); }

void ug_send(ug_core *core, uint8_t type, const uint8_t *payload, size_t n) {
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
    }
    size_t name = strlen(c->name); /* NUL-terminated within 65 bytes (config_ok) */
    memcpy(p + n, c->name, name);
    return n + name;
}

static uint16_t drive_code(float drive) {
    float code = drive * (float)UG_SETPOINT_SCALE + 0.5f;
    return (uint16_t)(code <= 0.0f ? 0.0f : (code >= 65535.0f ? 65535.0f : code));
}

void ug_send_telemetry(ug_core *core) {
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
    ug_send(core, UG_TELEMETRY, p, n);
}

void ug_send_sensors(ug_core *core) {
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
    ug_send(core, UG_SENSORS, p, UG_SENSORS_HEADER_SIZE + UG_SENSOR_SAMPLE_SIZE * (size_t)count);
}
