/*
 * The QEMU image's link tap: an independent reading of the SETPOINTS the firmware received, for the
 * tests that ask "did the host ever send a setpoint above the limit?". The USART1 interrupt hands each
 * byte to the core and, in the QEMU image, to this tap too; the main loop decodes the bytes here with
 * its own COBS decoder and its own bitwise CRC-32 (not the core's), and counts the SETPOINTS values of
 * valid frames: how many, the largest code, how many above the code of the limit. The board's debug
 * console prints the counts every second (ev stats ... max_setpoint_code= setpoints_above_limit=).
 * Pure logic, tested on the host (tests/test_firmware_board.py).
 */
#ifndef UG_LINK_TAP_H
#define UG_LINK_TAP_H

#include <stddef.h>
#include <stdint.h>

#define UG_TAP_MAX_BODY 1024u  /* docs/protocol.md: MAX_BODY, decoded bytes */

typedef struct {
    uint8_t body[UG_TAP_MAX_BODY];
    uint32_t length;       /* decoded bytes of this run so far */
    uint8_t left;          /* bytes left in the current COBS block */
    uint8_t zero_after;    /* the current block ends with an implied zero */
    uint8_t broken;        /* this run is not a frame we can read: skip to the next delimiter */
    uint16_t limit_code;   /* codes above this are counted */
    uint32_t frames;       /* valid SETPOINTS frames */
    uint32_t bad_frames;   /* runs that were not valid frames (COBS, length or CRC) */
    uint32_t setpoints;    /* values in valid SETPOINTS frames */
    uint32_t above;        /* ... above limit_code */
    uint32_t max_code;     /* the largest value seen */
} ug_tap_t;

void ug_tap_init(ug_tap_t *tap, uint16_t limit_code);
void ug_tap_feed(ug_tap_t *tap, const uint8_t *bytes, size_t n);
/* CRC-32/IEEE 802.3 (zlib's), bit by bit. */
uint32_t ug_tap_crc32(const uint8_t *data, size_t n);

#endif
