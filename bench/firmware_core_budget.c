/*
 * firmware_core_budget.c - the work the firmware core does per event, counted in instructions by valgrind's
 * callgrind on the host (bench/bench_firmware_core.py builds and runs it). Each measured operation runs between
 * CALLGRIND_ZERO_STATS and CALLGRIND_DUMP_STATS_AT(label), many times; the script keeps the largest count of
 * each label (the worst case).
 *
 * Measured: a SETPOINTS frame from its UART bytes to the buffer (12 values: 1 ms at 12 kHz; 240: the largest
 * frame; 96: 2 ms at 48 kHz, the fastest stream), a carrier block (1 ms: 48 drive samples, 192 DAC samples),
 * open loop and with the amplitude loop, an ADC block of 48 measured samples (limiter, trip, sensors, loop),
 * and a tick followed by a poll, with and without a TELEMETRY or SENSORS frame to build; with the force correction
 * (SETPOINTS_FORCE frames whose reference changes every frame, so every frame marks the buffer and every value's
 * pop at a frame's start evaluates the power; ADC blocks carrying the normal force), the same frame and blocks.
 */
#include <string.h>
#include <valgrind/callgrind.h>

#include "ug_internal.h"
#include "ug_sim.h"

static ug_sim sim;
static uint8_t body[UG_MAX_BODY], wire[UG_MAX_ENCODED + 8], tx[8192];
static int16_t dac[192];
static float amplitude[48], normal_force[48];
static uint16_t host_seq;
static uint32_t first_index;
static uint8_t with_force; /* SETPOINTS_FORCE frames and a configuration with the force correction */

static size_t frame(uint8_t type, const uint8_t *payload, size_t n) {
    body[0] = type;
    ug_put_u16(body + 1, host_seq++);
    memcpy(body + 3, payload, n);
    ug_put_u32(body + 3 + n, ug_crc32(body, 3 + n));
    size_t length = ug_cobs_encode(body, n + 7u, wire);
    wire[length++] = 0;
    return length;
}

static void command(uint8_t type, const uint8_t *payload, size_t n) {
    size_t length = frame(type, payload, n);
    ug_core_uart_rx(&sim.core, wire, length);
    ug_core_poll(&sim.core);
    (void)ug_core_uart_tx(&sim.core, tx, sizeof tx);
}

static size_t setpoints_frame(uint16_t count, uint32_t rate) {
    uint8_t payload[UG_SETPOINTS_FORCE_HEADER_SIZE + 2 * 240];
    ug_put_u32(payload, first_index);
    ug_put_u32(payload + 4, rate);
    ug_put_u16(payload + 8, count);
    size_t header = UG_SETPOINTS_HEADER_SIZE;
    if (with_force) { /* a reference that changes every frame: 0.4-0.6 N, exponent 1/3, the limit 0.75 */
        ug_put_f32(payload + 10, 0.4f + 0.001f * (float)(first_index % 200u));
        ug_put_f32(payload + 14, 0.3333f);
        ug_put_u16(payload + 18, 49151u);
        header = UG_SETPOINTS_FORCE_HEADER_SIZE;
    }
    for (uint16_t i = 0; i < count; i++) {
        ug_put_u16(payload + header + 2 * i, (uint16_t)(20000u + 97u * ((first_index + i) % 256u)));
    }
    first_index += count;
    return frame(with_force ? UG_SETPOINTS_FORCE : UG_SETPOINTS, payload, header + 2u * count);
}

static void start(uint8_t loop, uint32_t rate) {
    ug_config config;
    ug_sim_config_defaults(&config);
    if (with_force) {
        config.sensors |= UG_SENSOR_NORMAL_FORCE;
        config.features |= UG_FEATURE_FORCE_CORRECTION;
    }
    ug_sim_init(&sim, &config);
    host_seq = 0;
    first_index = 0;
    uint8_t on = 1, hello = 3;
    command(UG_HELLO, &hello, 1);
    command(UG_SET_LOOP, &loop, 1);
    command(UG_ENABLE, &on, 1);
    for (int k = 0; k < 20; k++) { /* a buffer well past its prefill */
        size_t length = setpoints_frame(240, rate);
        ug_core_uart_rx(&sim.core, wire, length);
        ug_core_poll(&sim.core);
    }
    (void)ug_core_uart_tx(&sim.core, tx, sizeof tx);
}

static void measure_frame(uint16_t count, uint32_t rate, const char *label) {
    start(0, rate);
    for (int k = 0; k < 50; k++) {
        size_t length = setpoints_frame(count, rate);
        float drive[48];
        ug_core_drive_block(&sim.core, drive, 48); /* keep the buffer from filling */
        CALLGRIND_ZERO_STATS;
        ug_core_uart_rx(&sim.core, wire, length);
        ug_core_poll(&sim.core);
        CALLGRIND_DUMP_STATS_AT(label);
    }
}

static void measure_blocks(uint8_t loop, const char *dac_label, const char *adc_label) {
    start(loop, 12000u);
    for (int k = 0; k < 50; k++) {
        CALLGRIND_ZERO_STATS;
        ug_core_dac_block(&sim.core, dac, 192);
        CALLGRIND_DUMP_STATS_AT(dac_label);
        for (int i = 0; i < 48; i++) {
            amplitude[i] = 3.0f + 0.01f * (float)((k + i) % 7);
        }
        for (int i = 0; i < 48; i++) {
            normal_force[i] = 0.5f + 0.001f * (float)((k + i) % 11);
        }
        CALLGRIND_ZERO_STATS;
        ug_core_adc_block(&sim.core, amplitude, with_force ? normal_force : NULL, NULL, 48);
        CALLGRIND_DUMP_STATS_AT(adc_label);
    }
}

static void measure_ticks(void) {
    start(0, 12000u);
    for (int k = 0; k < 100; k++) {
        float drive[48];
        ug_core_drive_block(&sim.core, drive, 48);
        ug_core_adc_block(&sim.core, amplitude, NULL, NULL, 48);
        CALLGRIND_ZERO_STATS;
        ug_core_tick(&sim.core);
        ug_core_poll(&sim.core);
        if (sim.core.tx_head != sim.core.tx_tail) { /* a TELEMETRY or SENSORS frame built and queued */
            CALLGRIND_DUMP_STATS_AT("tick and poll with a frame to send");
        } else {
            CALLGRIND_DUMP_STATS_AT("tick and poll");
        }
        (void)ug_core_uart_tx(&sim.core, tx, sizeof tx);
    }
}

int main(void) {
    measure_frame(12, 12000u, "SETPOINTS 12 values");
    measure_frame(240, 12000u, "SETPOINTS 240 values");
    measure_frame(96, 48000u, "SETPOINTS 96 values at 48 kHz");
    measure_blocks(0, "carrier block open loop", "ADC block open loop");
    measure_blocks(1, "carrier block amplitude loop", "ADC block amplitude loop");
    measure_ticks();
    with_force = 1;
    measure_frame(12, 12000u, "SETPOINTS_FORCE 12 values");
    measure_frame(240, 12000u, "SETPOINTS_FORCE 240 values");
    measure_blocks(1, "carrier block loop, force correction", "ADC block loop, force correction");
    return 0;
}
