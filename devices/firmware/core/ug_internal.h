/* ug_internal.h - what the core's files share (not for ports). */
#ifndef UG_INTERNAL_H
#define UG_INTERNAL_H

#include "ug_core.h"

#if defined(UG_CONFORMANCE_BREAKS) && UG_CONFORMANCE_BREAKS
#define UG_BROKEN(core, which) ((((core)->breaks) >> (which)) & 1u)
#else
#define UG_BROKEN(core, which) 0u
#endif

enum { UG_DECODE_NOTHING = 0, UG_DECODE_FRAME, UG_DECODE_ERROR };

/* ug_frame.c */
void ug_decoder_reset(ug_decoder *decoder);
int ug_decoder_feed(ug_decoder *decoder, uint8_t byte, uint16_t max_encoded);

/* ug_loop.c: the device-side limiter and the amplitude loop */
float ug_limit(ug_core *core, float drive, float floor);
float ug_loop_drive(ug_core *core, float target);
float ug_loop_brake_floor(const ug_core *core, float target);
void ug_loop_record(ug_core *core, float requested, float drive);
void ug_loop_measured(ug_core *core, size_t n);
void ug_loop_reset(ug_core *core);

/* ug_force.c: the force correction */
void ug_force_clear(ug_core *core);
void ug_force_mark(ug_core *core, uint32_t at, float force_n, float exponent, float limit);
void ug_force_popped(ug_core *core, uint32_t ordinal);
void ug_force_measured(ug_core *core, const float *normal_force_n, size_t n);
float ug_force_correct(const ug_core *core, float requested);

/* ug_dds.c */
void ug_dds_set(ug_core *core, float carrier_hz);

/* ug_core.c: events and faults */
void ug_post_event(ug_core *core, uint8_t kind, uint8_t a, uint16_t b, float value);
void ug_raise_fault(ug_core *core, uint16_t bit, uint16_t detail, float value);

/* ug_playback.c: the jitter buffer */
void ug_buffer_clear(ug_core *core);
void ug_buffer_push(ug_core *core, const uint8_t *codes, uint32_t first, uint16_t n);
void ug_set_rate(ug_core *core, uint32_t rate);

/* ug_state.c: the output's state */
void ug_stop_stream(ug_core *core);
void ug_forget_stream(ug_core *core);
void ug_disable(ug_core *core, uint8_t why);
void ug_enable(ug_core *core);
void ug_overheat(ug_core *core);

/* ug_tx.c: frames to the host */
void ug_send(ug_core *core, uint8_t type, const uint8_t *payload, size_t n);
void ug_ack(ug_core *core, uint16_t seq);
void ug_nak(ug_core *core, uint8_t type, uint16_t seq, uint8_t reason);
size_t ug_hello_reply(const ug_core *core, uint8_t *p);
/* TELEMETRY's payload into p (inside the lock: a copy of the state); its length */
size_t ug_telemetry_payload(ug_core *core, uint8_t *p);
/* SENSORS: swap the rings inside the lock (the samples waiting, and the number of the first), send outside it */
uint8_t ug_sensors_swap(ug_core *core, uint32_t *first_number);
void ug_send_sensors(ug_core *core, uint8_t count, uint32_t first_number);
/* replies kept while a frame's critical section held (ug_send in it), encoded and queued now */
void ug_outbox_flush(ug_core *core);

/* little-endian fields */
static inline void ug_put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void ug_put_u32(uint8_t *p, uint32_t v) {
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}
static inline uint16_t ug_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static inline uint32_t ug_get_u32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
void ug_put_f32(uint8_t *p, float v);
float ug_get_f32(const uint8_t *p);

#endif /* UG_INTERNAL_H */
