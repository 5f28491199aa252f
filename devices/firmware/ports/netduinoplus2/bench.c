/*
 * The budget image: runs the port's and the core's real-time work on the target and prints, on the
 * debug console, the instructions each call takes. Run under QEMU with `-icount shift=0`: every
 * instruction then takes 1 ns of virtual time, which SysTick (168 MHz of virtual time) counts, so
 * instructions = SysTick counts × 1000 / 168. A loop of known length calibrates the reading first.
 * bench/bench_firmware.py runs it; the README gives the figures and the cycle estimate drawn from them.
 */
#include "board.h"
#include "emulated_plate.h"
#include "port_logic.h"
#include "stm32f405.h"
#include "uart_ring.h"

#define COUNTS_PER_US 168u  /* SysTick at the core clock of virtual time */

static uint32_t elapsed_counts;

/* SysTick counting down from its reload without interrupts: a 24-bit window of 99 ms at 168 MHz. */
static void counter_start(void)
{
    SYST_CSR = 0u;
    SYST_RVR = 0x00FFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_ENABLE;
}

static uint32_t counter_now(void)
{
    return SYST_CVR;
}

/* Instructions per call of ``body`` over ``reps`` calls, in tenths, from the virtual time they took. */
static uint32_t tenths_per_call(void (*body)(void), uint32_t reps)
{
    counter_start();
    uint32_t before = counter_now();
    for (uint32_t i = 0; i < reps; i++) {
        body();
    }
    uint32_t after = counter_now();
    elapsed_counts = (before - after) & 0x00FFFFFFu;
    uint64_t instructions_x10 = (uint64_t)elapsed_counts * 10000u / COUNTS_PER_US;
    return (uint32_t)(instructions_x10 / reps);
}

static void report(const char *name, void (*body)(void), uint32_t reps)
{
    uint32_t tenths = tenths_per_call(body, reps);
    char line[120];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "bench ");
    at = ug_append_text(at, end, name);
    at = ug_append_text(at, end, " reps=");
    at = ug_append_u32(at, end, reps);
    at = ug_append_text(at, end, " instructions=");
    at = ug_append_u32(at, end, tenths / 10u);
    at = ug_append_text(at, end, ".");
    at = ug_append_u32(at, end, tenths % 10u);
    at = ug_append_text(at, end, " counts=");
    at = ug_append_u32(at, end, elapsed_counts);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

/* 1000 turns of a two-instruction loop, plus the call: about 2000 instructions */
static void calibration_loop(void)
{
    uint32_t n = 1000u;
    __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
}

static int16_t samples[BOARD_BLOCK_SAMPLES];
static uint16_t codes[BOARD_BLOCK_SAMPLES];

static void dac_block(void)
{
    ug_dac_block(samples, codes, BOARD_BLOCK_SAMPLES);
}

static ug_emulated_plate_t plate;

static void plate_step(void)
{
    (void)ug_emulated_plate_step(&plate, 0.5f, 25010.0f, 0.001f);
}

static ug_ring_t ring;

static void ring_frame(void)
{
    static const uint8_t frame[80] = {1};
    (void)ug_ring_write(&ring, frame, sizeof frame);
    ring.tail = ring.head;
}

int main(void)
{
    board_init();
    for (uint32_t i = 0; i < BOARD_BLOCK_SAMPLES; i++) {
        samples[i] = (int16_t)((i * 2621u) & 0x7FFFu);
    }
    ug_emulated_plate_init(&plate, 25000.0f, 200.0f, 0.0f, 8.0f);
    ug_ring_init(&ring);
    report("calibration_2000", calibration_loop, 100u);
    report("dac_block_250", dac_block, 100u);
    report("emulated_plate_step", plate_step, 1000u);
    report("uart_frame_80", ring_frame, 1000u);
    board_console_write("bench done\n");
    for (;;) {
        board_wait_for_interrupt();
    }
}
