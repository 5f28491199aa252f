#include "link_tap.h"

void ug_tap_init(ug_tap_t *tap, uint16_t limit_code)
{
    tap->length = 0u;
    tap->left = 0u;
    tap->zero_after = 0u;
    tap->broken = 0u;
    tap->limit_code = limit_code;
    tap->frames = tap->bad_frames = tap->setpoints = tap->above = tap->max_code = 0u;
}

uint32_t ug_tap_crc32(const uint8_t *data, size_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        crc ^= data[i];
        for (int bit = 0; bit < 8; bit++) {
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* a run ended at a delimiter: count it if it is a valid SETPOINTS frame */
static void frame_end(ug_tap_t *tap)
{
    uint32_t n = tap->length;
    if (tap->broken || tap->left != 0u || n < 7u) {
        if (n > 0u || tap->broken) {
            tap->bad_frames++;
        }
        return;
    }
    if (ug_tap_crc32(tap->body, n - 4u) != get_u32(tap->body + n - 4u)) {
        tap->bad_frames++;
        return;
    }
    const uint8_t *payload = tap->body + 3;
    uint32_t payload_length = n - 7u;
    if (tap->body[0] != 0x04u || payload_length < 10u) {
        return;  /* another valid frame */
    }
    uint32_t count = (uint32_t)payload[8] | ((uint32_t)payload[9] << 8);
    if (payload_length != 10u + 2u * count) {
        return;  /* the core refuses it (NAK 2): nothing played */
    }
    tap->frames++;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t code = (uint32_t)payload[10 + 2 * i] | ((uint32_t)payload[11 + 2 * i] << 8);
        tap->setpoints++;
        tap->max_code = code > tap->max_code ? code : tap->max_code;
        tap->above += code > tap->limit_code ? 1u : 0u;
    }
}

static void put(ug_tap_t *tap, uint8_t byte)
{
    if (tap->length >= UG_TAP_MAX_BODY) {
        tap->broken = 1u;
        return;
    }
    tap->body[tap->length++] = byte;
}

void ug_tap_feed(ug_tap_t *tap, const uint8_t *bytes, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint8_t byte = bytes[i];
        if (byte == 0u) {
            frame_end(tap);
            tap->length = 0u;
            tap->left = 0u;
            tap->zero_after = 0u;
            tap->broken = 0u;
            continue;
        }
        if (tap->broken) {
            continue;
        }
        if (tap->left == 0u) {  /* a code byte: the block's length, and whether a zero follows it */
            if (tap->zero_after) {
                put(tap, 0u);
            }
            tap->left = (uint8_t)(byte - 1u);
            tap->zero_after = byte != 0xFFu;
            continue;
        }
        put(tap, byte);
        tap->left--;
    }
}
