/*
 * fuzz_core.c - a libFuzzer harness for the firmware core (scripts/fuzz_firmware.sh builds and runs it with
 * clang -fsanitize=fuzzer,address,undefined; its last result is in the README).
 *
 * Each input is a script for one device from power-up: frames (valid ones built here, so the fuzzer gets past
 * the CRC; and raw bytes), time (1 ms ticks with drive rendered and a plate's amplitude measured), the stage
 * overheating, carrier blocks. After every step it checks what must always hold, and traps if not:
 *   - the drive stays within 0..the drive ceiling, and a plate up to twice as fast as configured, on or off
 *     resonance, never exceeds the limit (the device's limit binds, whatever the host sends);
 *   - every value of every accepted SETPOINTS frame is counted once (setpoints, overrun, late, discarded);
 *   - the buffer never holds more than its capacity; the state is one of the five;
 *   - what the device sends decodes: COBS, a CRC that matches, consecutive seqs from 0.
 * ASan and UBSan catch the rest (out-of-bounds, overflow, misaligned or uninitialised reads).
 */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "ug_internal.h"
#include "ug_sim.h"

#define CHECK(condition) do { if (!(condition)) __builtin_trap(); } while (0)

static ug_sim sim;
static uint8_t frame_body[UG_MAX_BODY];
static uint8_t frame_wire[UG_MAX_ENCODED + 8];
static uint8_t tx[8192];
static float drive[64], amplitude[64];
static int16_t dac[256];

typedef struct {
    uint64_t values_accepted_candidates; /* values in SETPOINTS frames sent, refused or not */
    uint16_t host_seq;
    uint16_t device_seq;
    int device_seq_known;
    uint32_t naks_seen;
    ug_decoder decoder;
} checker;

static checker check_state;

/* the device's output, decoded as a host would: every run a valid frame, seqs consecutive */
static void drain(void) {
    size_t n = ug_sim_take_tx(&sim, tx, sizeof tx);
    for (size_t i = 0; i < n; i++) {
        int result = ug_decoder_feed(&check_state.decoder, tx[i], UG_MAX_ENCODED);
        CHECK(result != UG_DECODE_ERROR);
        if (result == UG_DECODE_FRAME) {
            const uint8_t *body = check_state.decoder.body;
            size_t length = check_state.decoder.length;
            CHECK(ug_crc32(body, length - 4u) == ug_get_u32(body + length - 4u));
            uint16_t seq = ug_get_u16(body + 1);
            CHECK(!check_state.device_seq_known || seq == (uint16_t)(check_state.device_seq + 1u));
            check_state.device_seq = seq;
            check_state.device_seq_known = 1;
            CHECK(body[0] == UG_HELLO_REPLY || body[0] == UG_ACK || body[0] == UG_NAK || body[0] == UG_TELEMETRY ||
                  body[0] == UG_SENSORS);
        }
    }
}

/* a frame with correct CRC, after a 0x00 that ends whatever raw bytes came before (as a host resynchronises) */
static void send_frame(uint8_t type, const uint8_t *payload, size_t n) {
    static const uint8_t delimiter = 0;
    ug_sim_receive(&sim, &delimiter, 1u, 0u);
    frame_body[0] = type;
    ug_put_u16(frame_body + 1, check_state.host_seq++);
    memcpy(frame_body + 3, payload, n);
    ug_put_u32(frame_body + 3 + n, ug_crc32(frame_body, 3 + n));
    size_t length = ug_cobs_encode(frame_body, n + 7u, frame_wire);
    frame_wire[length++] = 0;
    ug_sim_receive(&sim, frame_wire, length, 0u);
}

/* the plate's envelope over n drive samples (the fastest plausible plate at most): its phasor along the drive's
   phase, signed (a braking drive is the carrier in antiphase), the amplitude its magnitude; the limit is checked on
   each sample, in either sign, and a brake never pulls the phasor through zero */
static float through_plate(float plate, const float *samples, unsigned n, float alpha, float gain,
                           const ug_config *config) {
    float lowest = (config->features & UG_FEATURE_BRAKING) ? -sim.core.limit_fraction - 1e-6f : 0.0f;
    for (unsigned i = 0; i < n; i++) {
        CHECK(samples[i] >= lowest && samples[i] <= sim.core.drive_ceiling + 1e-6f);
        plate = alpha * plate + (1.0f - alpha) * gain * samples[i] * config->full_scale_um_pp;
        CHECK(fabsf(plate) <= config->max_amplitude_um_pp * 1.0001f); /* the device's limit binds */
        CHECK(plate >= -1e-4f);                                       /* no brake through zero */
        amplitude[i % 64u] = fabsf(plate);
    }
    return plate;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    ug_config config;
    ug_sim_config_defaults(&config);
    config.sim_faults = 1;
    if (size < 2) {
        return 0;
    }
    config.max_version = (uint8_t)(2u + (data[0] & 1u));
    if (data[0] & 2u) {
        config.features |= UG_FEATURE_BRAKING;
    }
    float q_factor = 0.5f + 1.5f * (float)(data[1] & 0x0Fu) / 15.0f;  /* the plate's Q: 0.5x to 2x */
    float gain = 0.5f + 0.5f * (float)(data[1] >> 4) / 15.0f;          /* on or off resonance */
    CHECK(ug_sim_init(&sim, &config) == UG_OK);
    memset(&check_state, 0, sizeof check_state);
    ug_decoder_reset(&check_state.decoder);
    const ug_core *core = &sim.core;
    const float tau = q_factor * config.q / (3.14159265f * config.resonance_hz);
    const float alpha = expf(-1.0f / ((float)config.sample_rate_hz * tau));
    float plate = 0.0f;
    uint64_t sent_values = 0, refused_values = 0;
    size_t at = 2;
    while (at < size) {
        uint8_t op = data[at++];
        uint8_t length = at < size ? data[at] : 0u;
        switch (op & 7u) {
        case 0: case 1: { /* a valid frame: type, then up to `length` bytes of payload */
            if (at + 2u > size) {
                return 0;
            }
            uint8_t type = data[at + 1];
            at += 2;
            size_t n = length <= size - at ? length : size - at;
            uint32_t naks_before = core->naks;
            send_frame(type, data + at, n);
            if (type == UG_SETPOINTS && n >= 10u) {
                uint16_t count = ug_get_u16(data + at + 8);
                sent_values += count;
                if (core->naks != naks_before) {
                    refused_values += count;
                }
            }
            at += n;
            break;
        }
        case 2: { /* a SETPOINTS frame that is well formed: index, count and level from the script */
            if (at + 4u > size) {
                return 0;
            }
            uint8_t payload[10 + 2 * 240];
            uint16_t count = (uint16_t)(1u + data[at] % 240u);
            uint32_t first = (uint32_t)data[at + 1] * 97u;
            uint16_t code = (uint16_t)(data[at + 2] << 8 | data[at + 3]);
            ug_put_u32(payload, first);
            ug_put_u32(payload + 4, (op & 8u) ? 48000u : 12000u);
            ug_put_u16(payload + 8, count);
            for (uint16_t i = 0; i < count; i++) {
                ug_put_u16(payload + 10 + 2 * i, (uint16_t)(code + 37u * i));
            }
            uint32_t naks_before = core->naks;
            send_frame(UG_SETPOINTS, payload, 10u + 2u * count);
            sent_values += count;
            if (core->naks != naks_before) {
                refused_values += count;
            }
            at += 4;
            break;
        }
        case 3: { /* raw bytes on the link */
            at++;
            size_t n = length <= size - at ? length : size - at;
            ug_sim_receive(&sim, data + at, n, 0u);
            at += n;
            break;
        }
        case 4: case 5: { /* time: `length` ms of drive through the plate */
            at++;
            for (unsigned ms = 0; ms < (unsigned)(length % 64u) + 1u; ms++) {
                ug_sim_render(&sim, drive, 48u);
                plate = through_plate(plate, drive, 48u, alpha, gain, &config);
                ug_sim_sense(&sim, amplitude, NULL, NULL, 48u);
                drain();
            }
            break;
        }
        case 6: /* the stage overheats, or cools */
            at++;
            ug_sim_set_stage_hot(&sim, length & 1u);
            break;
        default: { /* carrier samples: the drive they carry goes through the plate too (no measurement) */
            at++;
            unsigned drive_samples = (length % 64u) + 1u;
            ug_sim_dac(&sim, dac, 4u * drive_samples);
            plate = through_plate(plate, sim.core.scratch, drive_samples, alpha, gain, &config);
            break;
        }
        }
        drain();
        CHECK(core->buf_count <= UG_BUFFER_CAPACITY && core->state <= UG_RAMP);
        CHECK(core->state == UG_OFF || core->buf_count <= core->capacity || core->rate == 0u);
        /* every value of every accepted SETPOINTS frame counted once */
        CHECK((uint64_t)core->setpoints + core->overrun + core->late + core->discarded == sent_values - refused_values);
    }
    return 0;
}
