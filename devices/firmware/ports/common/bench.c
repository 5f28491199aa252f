/*
 * The budget image: the port's and the core's real-time work, timed on the target under QEMU's instruction
 * counting. Run with `-icount shift=0`: every instruction then takes 1 ns of virtual time, and the board's bench
 * clock (board_bench_clock: the netduinoplus2's TIM5 counts virtual nanoseconds, the mps2-an386's TIMER1 PCLK's
 * 40 ns) times BOARD_BENCH_PER_COUNT is the instructions between two readings (to 1 and 40 instructions)
 * (a loop of known length calibrates this first). It plays the fastest stream the protocol allows,
 * 48 000 setpoints/s, for a second, through the same port glue the board image runs (port.c): SETPOINTS
 * frames handed to the core as the hardware's DMA delivers them (a frame at once) and, every other frame,
 * as QEMU's USART does (a byte an interrupt), each followed by the main loop's poll that decodes and
 * buffers it; then the 1 ms blocks that play them (each: the sensing piezo's block measured, the core's ADC
 * and DAC blocks, its tick), the polls after them (telemetry, SENSORS) and the bytes those queue for the
 * host. Four ways: 240-value and 48-value (1 ms) frames, in open loop and with the amplitude loop. Each line
 * on the debug console: `bench NAME calls=N mean=M max=X total=T` (instructions). bench/bench_firmware.py
 * runs it and turns the figures into cycles and CPU shares.
 */
#include <stddef.h>

#include "board.h"
#include "port.h"
#include "port_logic.h"

#define RATE_HZ 48000u       /* the protocol's fastest stream (the reference firmware's max_setpoint_rate_hz) */
#define VALUES 240u          /* the most a SETPOINTS frame carries */
#define FRAMES 200u          /* one second of the stream */

typedef struct {
    const char *name;
    uint32_t calls;
    uint32_t max;
    uint64_t total;
} figure_t;

static uint32_t overhead;  /* instructions of an empty measurement */

static uint32_t counter(void)
{
    return board_bench_clock() * BOARD_BENCH_PER_COUNT;  /* differences modulo 2^32 stay right */
}

static void record(figure_t *f, uint32_t start, uint32_t stop)
{
    uint32_t n = stop - start;
    n = n > overhead ? n - overhead : 0u;
    f->calls++;
    f->total += n;
    f->max = n > f->max ? n : f->max;
}

static void report(const figure_t *f)
{
    char line[160];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "bench ");
    at = ug_append_text(at, end, f->name);
    at = ug_append_text(at, end, " calls=");
    at = ug_append_u32(at, end, f->calls);
    at = ug_append_text(at, end, " mean=");
    at = ug_append_fixed(at, end, f->calls ? (float)f->total / (float)f->calls : 0.0f, 1u);
    at = ug_append_text(at, end, " max=");
    at = ug_append_u32(at, end, f->max);
    at = ug_append_text(at, end, " total=");
    at = ug_append_u32(at, end, (uint32_t)f->total);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

/* 1000 turns of a two-instruction loop, plus the call: 2006 instructions counted by hand */
static void __attribute__((noinline)) calibration_loop(void)
{
    uint32_t n = 1000u;
    __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
}

/* ---- frames as the host sends them (docs/protocol.md) -------------------------------------------------- */
static uint8_t body[UG_MAX_BODY];
static uint8_t frame[UG_MAX_ENCODED + 2];
static uint16_t seq;

static void put_u16(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    put_u16(p, v);
    put_u16(p + 2, v >> 16);
}

/* type, seq and payload (already in body + 3) → an encoded frame with its delimiter; returns its length */
static size_t encode(uint8_t type, size_t payload)
{
    body[0] = type;
    put_u16(body + 1, seq++);
    put_u32(body + 3 + payload, ug_crc32(body, 3 + payload));
    size_t n = ug_cobs_encode(body, payload + 7u, frame);
    frame[n++] = 0u;
    return n;
}

static size_t setpoints_frame(uint32_t first, uint32_t count)
{
    put_u32(body + 3, first);
    put_u32(body + 7, RATE_HZ);
    put_u16(body + 11, count);
    for (uint32_t i = 0; i < count; i++) {
        put_u16(body + 13 + 2 * i, ((first + i) * 2654435761u >> 16) % 49152u);  /* a rough texture within the limit */
    }
    return encode(0x04u, 10u + 2u * count);
}

static void deliver(size_t n)
{
    board_link_received(frame, n);
    ug_core_poll(port_core());
}

static void command(uint8_t type, uint8_t value)
{
    body[3] = value;
    deliver(encode(type, 1u));
}

/* ---- one second of the fastest stream ---------------------------------------------------------------- */
static figure_t rx_byte, rx_frame, frame_poll, block_work, tick_poll, tx_chunk, plate_block;
static uint32_t tx_bytes;

static void stream_second(uint32_t values_per_frame)
{
    ug_core *core = port_core();
    uint32_t index = 0, half = 0;
    uint32_t blocks_per_frame = 2u * values_per_frame * 1000u / RATE_HZ;  /* two 240-value frames: 10 ms of blocks */
    for (uint32_t f = 0; f < RATE_HZ / values_per_frame; f += 2u) {  /* two frames a turn, two ways */
        size_t n = setpoints_frame(index, values_per_frame);
        index += values_per_frame;
        for (size_t i = 0; i < n; i++) {  /* QEMU's way: a byte an interrupt */
            uint32_t t0 = counter();
            board_link_received(&frame[i], 1u);
            record(&rx_byte, t0, counter());
        }
        uint32_t t0 = counter();
        ug_core_poll(core);
        record(&frame_poll, t0, counter());
        n = setpoints_frame(index, values_per_frame);  /* the hardware's: the frame DMA'd, handed over at once */
        index += values_per_frame;
        t0 = counter();
        board_link_received(frame, n);
        record(&rx_frame, t0, counter());
        t0 = counter();
        ug_core_poll(core);
        record(&frame_poll, t0, counter());
        for (uint32_t b = 0; b < blocks_per_frame; b++) {
            t0 = counter();
            board_emulate_block(half);
            record(&plate_block, t0, counter());
            t0 = counter();
            port_block(half);
            record(&block_work, t0, counter());
            half ^= 1u;
            t0 = counter();
            ug_core_poll(core);
            record(&tick_poll, t0, counter());
            static uint8_t chunk[256];
            for (;;) {
                t0 = counter();
                size_t taken = board_link_take(chunk, sizeof chunk);
                uint32_t t1 = counter();
                if (taken == 0u) {
                    break;
                }
                record(&tx_chunk, t0, t1);
                tx_bytes += (uint32_t)taken;
            }
        }
        ug_event event;
        while (ug_core_next_event(core, &event)) {
        }
    }
}

/* the block's parts, timed one by one on a core playing the stream (a second pass, after the others) */
static figure_t part_sense = {"part_sense_240", 0u, 0u, 0u}, part_adc = {"part_core_adc_block_48", 0u, 0u, 0u},
                part_dac = {"part_core_dac_block_240", 0u, 0u, 0u}, part_codes = {"part_dac_codes_240", 0u, 0u, 0u},
                part_tick = {"part_core_tick", 0u, 0u, 0u}, part_status = {"part_core_status", 0u, 0u, 0u};

static void block_parts(void)
{
    static ug_sense_t sense;
    static float amplitude[BOARD_BLOCK_DRIVE];
    static int16_t carrier[BOARD_BLOCK_SAMPLES];
    static ug_status status;
    ug_core *core = port_core();
    ug_sense_init(&sense, (float)BOARD_DAC_RATE_HZ, 0.0024f, 2048.0f);
    ug_sense_set_carrier(&sense, 25000.0f);
    uint32_t index = 1000000u, half = 0;
    command(0x03u, 0u);
    command(0x07u, 1u);
    command(0x03u, 1u);
    for (uint32_t f = 0; f < 200u; f++) {
        deliver(setpoints_frame(index, VALUES));
        index += VALUES;
        for (uint32_t b = 0; b < 5u; b++) {
            board_emulate_block(half);
            uint32_t t0 = counter();
            (void)ug_sense_block(&sense, board_adc_half(half), BOARD_BLOCK_DRIVE, BOARD_OVERSAMPLE, amplitude);
            record(&part_sense, t0, counter());
            t0 = counter();
            (void)ug_core_adc_block(core, amplitude, NULL, NULL, BOARD_BLOCK_DRIVE);
            record(&part_adc, t0, counter());
            t0 = counter();
            ug_core_dac_block(core, carrier, BOARD_BLOCK_SAMPLES);
            record(&part_dac, t0, counter());
            t0 = counter();
            ug_dac_block(carrier, board_dac_half(half), BOARD_BLOCK_SAMPLES);
            record(&part_codes, t0, counter());
            t0 = counter();
            ug_core_tick(core);
            record(&part_tick, t0, counter());
            t0 = counter();
            ug_core_status(core, &status);
            record(&part_status, t0, counter());
            half ^= 1u;
            ug_core_poll(core);
            static uint8_t chunk[256];
            while (board_link_take(chunk, sizeof chunk) != 0u) {
            }
        }
        ug_event event;
        while (ug_core_next_event(core, &event)) {
        }
    }
    report(&part_sense);
    report(&part_adc);
    report(&part_dac);
    report(&part_codes);
    report(&part_tick);
    report(&part_status);
}

static void reset_figures(const char *suffix)
{
    (void)suffix;
    figure_t *all[] = {&rx_byte, &rx_frame, &frame_poll, &block_work, &tick_poll, &tx_chunk, &plate_block};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) {
        all[i]->calls = 0u;
        all[i]->max = 0u;
        all[i]->total = 0u;
    }
    tx_bytes = 0u;
    uint32_t count, longest;
    port_critical_figures(&count, &longest);  /* forget what came before */
}

static void report_all(const char *mode)
{
    static char names[7][48];
    const char *bases[] = {"rx_byte", "rx_frame", "frame_poll", "block", "tick_poll", "tx_chunk", "emulated_plate_block"};
    figure_t *all[] = {&rx_byte, &rx_frame, &frame_poll, &block_work, &tick_poll, &tx_chunk, &plate_block};
    for (size_t i = 0; i < 7u; i++) {
        char *end = names[i] + sizeof names[i];
        char *at = ug_append_text(names[i], end, bases[i]);
        at = ug_append_text(at, end, "_");
        (void)ug_append_text(at, end, mode);
        all[i]->name = names[i];
        report(all[i]);
    }
    char line[96];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "bench tx_bytes_");
    at = ug_append_text(at, end, mode);
    at = ug_append_text(at, end, " calls=");
    at = ug_append_u32(at, end, tx_bytes);
    (void)ug_append_text(at, end, " mean=1.0 max=1 total=0\n");
    board_console_write(line);
    uint32_t count, longest;
    port_critical_figures(&count, &longest);  /* the block interrupt masked: the longest section of this second */
    longest *= BOARD_BENCH_PER_COUNT;
    longest = longest > overhead ? longest - overhead : 0u;
    at = ug_append_text(line, end, "bench masked_");
    at = ug_append_text(at, end, mode);
    at = ug_append_text(at, end, " calls=");
    at = ug_append_u32(at, end, count);
    at = ug_append_text(at, end, " mean=0.0 max=");
    at = ug_append_u32(at, end, longest);
    (void)ug_append_text(at, end, " total=0\n");
    board_console_write(line);
}

int main(void)
{
    board_init();
    board_bench_start();  /* no interrupt counted into the figures; the bench clock running */
    uint32_t t0 = counter();
    overhead = counter() - t0;  /* the reading itself */

    figure_t calibration = {"calibration_2006", 0u, 0u, 0u};
    for (int i = 0; i < 100; i++) {
        t0 = counter();
        calibration_loop();
        record(&calibration, t0, counter());
    }
    report(&calibration);

    ug_config config;
    float um_pp_per_code = 1.0f;
    port_configure(&config, &um_pp_per_code);
    if (port_start(&config, um_pp_per_code) != UG_OK) {
        board_console_write("bench failed: the core refused its configuration\n");
        board_fault_stop();
    }
    static const char *const modes[] = {"open_240", "loop_240", "open_48", "loop_48"};
    static const uint32_t values[] = {VALUES, VALUES, RATE_HZ / 1000u, RATE_HZ / 1000u};
    uint32_t commands_count = 0u, commands_longest = 0u;
    for (uint32_t m = 0; m < 4u; m++) {
        uint32_t count, longest;
        port_critical_figures(&count, &longest);  /* forget what came before */
        command(0x03u, 0u);                     /* ENABLE 0: rests, forgets the stream (the output silenced) */
        command(0x07u, m % 2u);                 /* SET_LOOP: open loop, or the amplitude loop */
        command(0x03u, 1u);                     /* ENABLE 1 */
        port_critical_figures(&count, &longest);
        longest *= BOARD_BENCH_PER_COUNT;
        commands_count += count;
        commands_longest = longest > commands_longest ? longest : commands_longest;
        reset_figures(modes[m]);
        stream_second(values[m]);
        report_all(modes[m]);
    }
    figure_t commands = {"masked_commands", commands_count, commands_longest > overhead ? commands_longest - overhead
                                                                                        : 0u, 0u};
    report(&commands);  /* ENABLE 0 (a disable: both DAC halves silenced inside the section), SET_LOOP, ENABLE 1 */
    block_parts();
    ug_status status;
    ug_core_status(port_core(), &status);
    char line[160];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "bench done setpoints=");
    at = ug_append_u32(at, end, status.setpoints);
    at = ug_append_text(at, end, " underruns=");
    at = ug_append_u32(at, end, status.fault_counts[4]);
    at = ug_append_text(at, end, " naks=");
    at = ug_append_u32(at, end, status.naks);
    at = ug_append_text(at, end, " overrun=");
    at = ug_append_u32(at, end, status.overrun_setpoints);
    at = ug_append_text(at, end, " late=");
    at = ug_append_u32(at, end, status.late_setpoints);
    at = ug_append_text(at, end, " lost=");
    at = ug_append_u32(at, end, status.lost_setpoints);
    at = ug_append_text(at, end, " buffered=");
    at = ug_append_u32(at, end, status.buffered);
    at = ug_append_text(at, end, " playback=");
    at = ug_append_u32(at, end, status.playback);
    at = ug_append_text(at, end, " frames=");
    at = ug_append_u32(at, end, status.frames_ok);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
    for (;;) {
        board_wait_for_interrupt();
    }
}
