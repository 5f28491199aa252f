/* ug_frame.c - CRC-32, COBS encoding, and the byte-at-a-time frame decoder (docs/protocol.md, Framing). */
#include <string.h>

#include "ug_internal.h"

#include "crc_table.inc"

uint32_t ug_crc32(const uint8_t *data, size_t n) {
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        crc = crc_table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
    }
    return crc ^ 0xFFFFFFFFu;
}

size_t ug_cobs_encode(const uint8_t *in, size_t n, uint8_t *out) {
    size_t code_at = 0, written = 1;
    uint8_t code = 1;
    for (size_t i = 0; i < n; i++) {
        if (in[i] != 0) {
            out[written++] = in[i];
            code++;
        }
        if (in[i] == 0 || code == 0xFF) {
            out[code_at] = code;
            code = 1;
            code_at = written++;
            if (in[i] != 0 && i + 1 == n) { /* a full block ends the input: no empty block after it */
                return written - 1;
            }
        }
    }
    out[code_at] = code;
    return written;
}

void ug_decoder_reset(ug_decoder *decoder) {
    decoder->length = 0;
    decoder->encoded = 0;
    decoder->code = 0;
    decoder->left = 0;
    decoder->bad = 0;
}

static void append(ug_decoder *decoder, uint8_t byte) {
    if (decoder->length < UG_MAX_BODY) {
        decoder->body[decoder->length] = byte;
    }
    if (decoder->length <= UG_MAX_BODY) {
        decoder->length++; /* one past UG_MAX_BODY marks "too long" */
    }
}

/*
 * One byte of the link. Returns UG_DECODE_FRAME when a run ended at a 0x00 with a decoded body of
 * 7..MAX_BODY bytes (in decoder->body, decoder->length), UG_DECODE_ERROR for a framing error (a run
 * longer than max_encoded without a delimiter, counted once; invalid COBS; too short or too long
 * decoded), else UG_DECODE_NOTHING.
 */
int ug_decoder_feed(ug_decoder *decoder, uint8_t byte, uint16_t max_encoded) {
    if (byte == 0) {
        if (decoder->discarding) {
            decoder->discarding = 0;
            ug_decoder_reset(decoder);
            return UG_DECODE_NOTHING;
        }
        if (decoder->encoded == 0) {
            return UG_DECODE_NOTHING; /* idle line, padding */
        }
        int result = (decoder->bad || decoder->left != 0 || decoder->length < UG_MIN_BODY ||
                      decoder->length > UG_MAX_BODY) ? UG_DECODE_ERROR : UG_DECODE_FRAME;
        uint16_t length = decoder->length;
        ug_decoder_reset(decoder);
        decoder->length = length; /* the caller reads the body before the next byte */
        return result;
    }
    if (decoder->discarding) {
        return UG_DECODE_NOTHING;
    }
    if (decoder->encoded == 0) {
        decoder->length = 0;
    }
    decoder->encoded++;
    if (decoder->encoded > max_encoded) {
        ug_decoder_reset(decoder);
        decoder->discarding = 1;
        return UG_DECODE_ERROR;
    }
    if (decoder->left == 0) {
        if (decoder->encoded > 1 && decoder->code != 0xFF) {
            append(decoder, 0); /* the zero the previous block stood for */
        }
        decoder->code = byte;
        decoder->left = (uint8_t)(byte - 1);
    } else {
        append(decoder, byte);
        decoder->left--;
    }
    return UG_DECODE_NOTHING;
}

void ug_put_f32(uint8_t *p, float v) {
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    ug_put_u32(p, bits);
}

float ug_get_f32(const uint8_t *p) {
    uint32_t bits = ug_get_u32(p);
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}
