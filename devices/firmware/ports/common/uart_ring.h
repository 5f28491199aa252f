/*
 * A single-producer single-consumer byte ring for the UART: the interrupt handler fills the
 * receive ring and drains the transmit ring; the main loop does the other side. Lock-free:
 * each side writes only its own index, and a 32-bit aligned store is atomic on Cortex-M.
 * Pure logic, compiled for the host too (tests/test_firmware_board.py).
 */
#ifndef UG_UART_RING_H
#define UG_UART_RING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define UG_RING_SIZE 2048u  /* a power of two; 2048 bytes is 22 ms of a 921 600 baud link */

typedef struct {
    uint8_t bytes[UG_RING_SIZE];
    volatile uint32_t head;  /* written by the producer only: total bytes put */
    volatile uint32_t tail;  /* written by the consumer only: total bytes taken */
    volatile uint32_t dropped;  /* bytes the producer found no room for (producer only) */
} ug_ring_t;

static inline void ug_ring_init(ug_ring_t *ring)
{
    ring->head = 0u;
    ring->tail = 0u;
    ring->dropped = 0u;
}

static inline uint32_t ug_ring_used(const ug_ring_t *ring)
{
    return ring->head - ring->tail;  /* unsigned wrap-around keeps this right past 2^32 */
}

static inline uint32_t ug_ring_free(const ug_ring_t *ring)
{
    return UG_RING_SIZE - ug_ring_used(ring);
}

/* Producer: put one byte; false (and counted in ``dropped``) when full. */
static inline bool ug_ring_put(ug_ring_t *ring, uint8_t byte)
{
    uint32_t head = ring->head;
    if (head - ring->tail >= UG_RING_SIZE) {
        ring->dropped++;
        return false;
    }
    ring->bytes[head & (UG_RING_SIZE - 1u)] = byte;
    __asm__ volatile("" ::: "memory");  /* the byte is stored before the index that publishes it */
    ring->head = head + 1u;
    return true;
}

/* Consumer: take one byte into *byte; false when empty. */
static inline bool ug_ring_get(ug_ring_t *ring, uint8_t *byte)
{
    uint32_t tail = ring->tail;
    if (ring->head == tail) {
        return false;
    }
    *byte = ring->bytes[tail & (UG_RING_SIZE - 1u)];
    __asm__ volatile("" ::: "memory");
    ring->tail = tail + 1u;
    return true;
}

/* Producer: put all of ``length`` bytes or none (a frame is never cut); false when it does not fit. */
static inline bool ug_ring_write(ug_ring_t *ring, const uint8_t *data, size_t length)
{
    if (length > ug_ring_free(ring)) {
        ring->dropped += (uint32_t)length;
        return false;
    }
    uint32_t head = ring->head;
    for (size_t i = 0; i < length; i++) {
        ring->bytes[(head + (uint32_t)i) & (UG_RING_SIZE - 1u)] = data[i];
    }
    __asm__ volatile("" ::: "memory");
    ring->head = head + (uint32_t)length;
    return true;
}

#endif
