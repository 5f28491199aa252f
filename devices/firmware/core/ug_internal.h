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
float ug_limit(ug_core *core, float drive);
float ug_loop_drive(ug_core *core, float target);
void ug_loop_record(ug_core *core, float requested, float drive);
void ug_loop_measured(ug_core *core, size_t n);
void ug_loop_reset(ug_core *core);

/* ug_dds.c */
void ug_dds_set(ug_core *core, float carrier_hz);

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
