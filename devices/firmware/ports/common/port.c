/*
 * The boards' glue: ultraglide's firmware core (devices/firmware/core) joined to a board (its board.h: the
 * netduinoplus2's in ports/netduinoplus2, the mps2-an386's in ports/mps2-an386; names below are the
 * netduinoplus2's, the mps2-an386's are in its board.h).
 *
 * Contexts (ug_port.h): the main loop hands the link's bytes to the core (under QEMU USART1's receive
 * interrupt, priority 0x40, hands each byte over: only it writes the core's receive ring); one block
 * interrupt (0x60: DMA2's on hardware, SysTick's under QEMU, board.h) measures the block the ADC just
 * sampled, gives it to the core (ug_core_adc_block), has the core fill the next DAC block
 * (ug_core_dac_block) and ticks it (ug_core_tick: one block is one millisecond); the main loop polls the
 * core (frames, telemetry, SENSORS), has the board send what it queued and prints the core's events on the debug
 * console (USART2), one line each: `ev NAME key=value ...`, read by devices/firmware/qemu.py. The core's
 * critical sections raise BASEPRI to the block interrupt's priority, so the link's interrupt is never
 * masked.
 *
 * Timing of a block: the ADC half just measured was played by the DAC half the core filled two blocks ago;
 * since then the core has filled the other half (playing now), so its measurement arrives one block
 * (BOARD_BLOCK_DRIVE drive samples) behind its newest drive: config.sense_delay_samples.
 */
#include <stddef.h>

#include "port.h"

#include "board.h"
#include "emulation_config.h"
#include "link_tap.h"
#include "port_logic.h"
#include "uart_ring.h"

/* The sensing chain's gain on hardware: um peak-to-peak of plate motion per ADC code of peak-to-peak
   swing. This reference assumes the piezo's conditioning maps 10 um p-p to the ADC's full range;
   calibrate it for a real plate (docs/firmware.md). */
#define BOARD_SENSE_UM_PP_PER_CODE (10.0f / 4096.0f)
/* Under QEMU the emulated piezo maps 1.25 x full scale to the ADC's range: room above full drive. */
#define QEMU_SENSE_SPAN 1.25f

static ug_core core;

ug_core *port_core(void)
{
    return &core;
}
static ug_sense_t sense;
static float amplitude[BOARD_BLOCK_DRIVE];     /* block interrupt only */
static int16_t carrier[BOARD_BLOCK_SAMPLES];
static ug_status block_status;
static float sensed_carrier_hz;
static volatile float peak_measured_um_pp;    /* the largest amplitude the core was given */
static volatile uint32_t blocks;
static volatile uint32_t work;                 /* an interrupt left the main loop something to do */
static volatile uint32_t link_rx_bytes, link_tx_bytes;
static uint32_t last_stats;
static uint32_t main_last_us, main_max_gap_us;  /* the longest the main loop went between two turns */
#ifdef UG_BOARD_QEMU
static uint32_t clock_reads_told;  /* the board's clock readings the console has told (console_clock_read) */
#endif

/* what the image is, as its boot line says it (each board's Makefile builds the variants) */
#if defined(UG_BOARD_BENCH)
#define UG_VARIANT_NAME "bench"     /* the budget image (bench.c), run under QEMU's instruction counter */
#elif defined(UG_BOARD_QEMU)
#define UG_VARIANT_NAME "qemu"      /* the emulated board: its plate emulated, the link tapped */
#else
#define UG_VARIANT_NAME "hardware"  /* the real board */
#endif

#if defined(UG_BOARD_QEMU) && !defined(UG_BOARD_BENCH)
#define UG_LINK_TAP 1  /* the QEMU image's independent reading of the setpoints received (link_tap.h) */
static ug_ring_t tap_ring;
static ug_tap_t tap;
#endif

/* ---- the port interface (ug_port.h) ----------------------------------------------------------------- */
static uint32_t critical_depth, critical_saved;

#ifdef UG_BOARD_BENCH
/* the budget image times every masked section (instructions under -icount shift=0: TIM5's virtual ns) */
static uint32_t critical_started;
static uint32_t critical_max, critical_count;

void port_critical_figures(uint32_t *count, uint32_t *longest)
{
    *count = critical_count;
    *longest = critical_max;
    critical_count = 0u;
    critical_max = 0u;
}
#endif

void ug_port_critical_enter(void *port)
{
    (void)port;
    uint32_t previous = board_mask_blocks();
    if (critical_depth++ == 0u) {
        critical_saved = previous;
#ifdef UG_BOARD_BENCH
        critical_started = board_bench_clock();
#endif
    }
}

void ug_port_critical_exit(void *port)
{
    (void)port;
    if (critical_depth > 0u && --critical_depth == 0u) {
#ifdef UG_BOARD_BENCH
        uint32_t took = board_bench_clock() - critical_started;
        critical_max = took > critical_max ? took : critical_max;
        critical_count++;
#endif
        board_unmask_blocks(critical_saved);
    }
}

void ug_port_tx_ready(void *port)
{
    (void)port;  /* the main loop starts the transmitter after every poll */
}

void ug_port_output_safe(void *port, uint8_t why)
{
    (void)port;
    (void)why;
    board_output_safe();  /* both DAC halves to mid-scale: the DMA plays silence from its next word */
}

uint32_t ug_port_samples_since_block(void *port)
{
    (void)port;  /* where the ADC is within the block it fills now (board.c): CLOCK_REPLY to the drive sample */
    return board_samples_since_block();
}

void ug_port_sim_fault(void *port, uint8_t kind, uint16_t duration_ms)
{
    (void)port;  /* never called: a board answers SIM_FAULT with NAK 4 (config.sim_faults = 0) */
    (void)kind;
    (void)duration_ms;
}

/* ---- the link ------------------------------------------------------------------------------------------- */
void board_link_received(const uint8_t *bytes, size_t n)
{
    work = 1u;
    if (n == 0u) {
        return;  /* the hardware's idle-line interrupt: only a wake-up */
    }
    ug_core_uart_rx(&core, bytes, n);
    link_rx_bytes += (uint32_t)n;
#ifdef UG_LINK_TAP
    for (size_t i = 0; i < n; i++) {
        (void)ug_ring_put(&tap_ring, bytes[i]);
    }
#endif
}

size_t board_link_take(uint8_t *out, size_t max)
{
    size_t n = ug_core_uart_tx(&core, out, max);
    link_tx_bytes += (uint32_t)n;
    return n;
}

/* ---- one block (the block interrupt) ---------------------------------------------------------------- */
void port_block(uint32_t half)
{
    float peak = ug_sense_block(&sense, board_adc_half(half), BOARD_BLOCK_DRIVE, BOARD_OVERSAMPLE, amplitude);
    size_t cut = ug_core_block(&core, amplitude, NULL, NULL, BOARD_BLOCK_DRIVE, carrier, BOARD_BLOCK_SAMPLES);
    ug_dac_block(carrier, board_dac_half(half), BOARD_BLOCK_SAMPLES);
    ug_core_status(&core, &block_status);
    if (cut < BOARD_BLOCK_DRIVE) {
        board_dac_blank(half ^ 1u);  /* a trip (ug_port_output_safe blanked both; the refill above is silent too) */
    }
    if (block_status.carrier_hz != sensed_carrier_hz) {
        sensed_carrier_hz = block_status.carrier_hz;
        ug_sense_set_carrier(&sense, sensed_carrier_hz);
    }
    if (peak > peak_measured_um_pp) {
        peak_measured_um_pp = peak;
    }
    blocks++;
    work = 1u;
    ug_marks_block();
}

void port_lost(uint32_t lost_blocks)
{
    ug_core_lost_time(&core, lost_blocks);  /* one block is one millisecond */
    blocks += lost_blocks;
    work = 1u;
    ug_marks_block();
}

/* ---- the console ---------------------------------------------------------------------------------------- */
static const char *const fault_names[UG_FAULT_BITS] = {"watchdog", "trip", "over-limit", "overrun", "underrun",
                                                      "bad-command", "overheat", "reserved"};
static const char *const why_names[] = {"unknown", "host", "trip", "overheat", "hello"};

static char *append_pair(char *at, char *end, const char *key, uint32_t value)
{
    at = ug_append_text(at, end, " ");
    at = ug_append_text(at, end, key);
    at = ug_append_text(at, end, "=");
    return ug_append_u32(at, end, value);
}

static char *append_fixed_pair(char *at, char *end, const char *key, float value, uint32_t decimals)
{
    at = ug_append_text(at, end, " ");
    at = ug_append_text(at, end, key);
    at = ug_append_text(at, end, "=");
    return ug_append_fixed(at, end, value, decimals);
}

static void console_event(const ug_event *e)
{
    char line[160];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "ev ");
    switch (e->kind) {
    case UG_EV_HELLO:
        at = ug_append_text(at, end, "hello");
        at = append_pair(at, end, "host_version", e->a);
        at = append_pair(at, end, "version", e->b);
        break;
    case UG_EV_CARRIER:
        at = ug_append_text(at, end, "carrier");
        at = append_fixed_pair(at, end, "carrier_hz", e->value, 3u);
        break;
    case UG_EV_ENABLED:
        at = ug_append_text(at, end, "enabled");
        break;
    case UG_EV_DISABLED:
        at = ug_append_text(at, end, "disabled reason=");
        at = ug_append_text(at, end, why_names[e->a < 5u ? e->a : 0u]);
        break;
    case UG_EV_STREAM_STARTED:
        at = ug_append_text(at, end, "stream_started");
        at = append_pair(at, end, "rate_hz", (uint32_t)e->value);
        break;
    case UG_EV_STREAM_STOPPED:
        at = ug_append_text(at, end, "stream_stopped");
        break;
    case UG_EV_FAULT:
        at = ug_append_text(at, end, e->a == 0u ? "watchdog fault=" : "fault fault=");
        at = ug_append_text(at, end, fault_names[e->a & (UG_FAULT_BITS - 1u)]);
        if (e->a == 1u || e->a == 2u) {  /* trip, over-limit: what was measured */
            at = append_fixed_pair(at, end, "measured_um_pp", e->value, 4u);
        } else if (e->a == 5u) {  /* bad-command: the command and the NAK's reason */
            at = append_pair(at, end, "command", (uint32_t)(e->b >> 8));
            at = append_pair(at, end, "reason", (uint32_t)(e->b & 0xFFu));
        }
        break;
    case UG_EV_LOOP:
        at = ug_append_text(at, end, "loop mode=");
        at = ug_append_text(at, end, e->a ? "amplitude" : "open");
        break;
    default:
        return;
    }
    uint32_t ms = (uint32_t)(e->sample / (BOARD_DRIVE_RATE_HZ / 1000u));  /* the core's clock, as plate-sim's */
    at = append_pair(at, end, "t_s", ms / 1000u);
    at = ug_append_text(at, end, ".");
    at = ug_append_text(at, end, ms % 1000u < 100u ? (ms % 1000u < 10u ? "00" : "0") : "");
    at = ug_append_u32(at, end, ms % 1000u);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

static void console_stats(void)
{
    ug_status s;
    ug_port_critical_enter(NULL);
    ug_core_status(&core, &s);
    ug_port_critical_exit(NULL);
    char line[768];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "ev stats");
    at = append_pair(at, end, "frames", s.frames_ok);
    at = append_pair(at, end, "setpoints", s.setpoints);
    at = append_pair(at, end, "crc_errors", s.crc_errors);
    at = append_pair(at, end, "framing_errors", s.framing_errors);
    at = append_pair(at, end, "lost_setpoints", s.lost_setpoints);
    at = append_pair(at, end, "late_setpoints", s.late_setpoints);
    at = append_pair(at, end, "overrun_setpoints", s.overrun_setpoints);
    at = append_pair(at, end, "discarded_setpoints", s.discarded_setpoints);
    at = append_pair(at, end, "watchdog_trips", s.fault_counts[0]);
    at = append_pair(at, end, "trips", s.fault_counts[1]);
    at = append_pair(at, end, "over_limits", s.fault_counts[2]);
    at = append_pair(at, end, "underruns", s.fault_counts[4]);
    at = append_pair(at, end, "naks", s.naks);
    at = append_pair(at, end, "rx_bytes", link_rx_bytes);
    at = append_pair(at, end, "tx_bytes", link_tx_bytes);
    at = append_pair(at, end, "rx_overflows", s.rx_overflows + board_link_overruns());
    at = append_pair(at, end, "tx_dropped", s.tx_dropped);
    at = append_fixed_pair(at, end, "peak_um_pp", peak_measured_um_pp, 4u);
    at = append_pair(at, end, "blocks", blocks);
    at = append_pair(at, end, "late_blocks", board_late_blocks());
    at = append_pair(at, end, "lost_ms", s.lost_ms);
    at = append_pair(at, end, "dma_errors", board_dma_errors());
    at = append_pair(at, end, "dac_underruns", board_dac_underruns());
#ifdef UG_BOARD_QEMU
    at = append_fixed_pair(at, end, "plate_peak_um_pp", board_plate_peak_um_pp(), 4u);
    at = append_pair(at, end, "skipped_ms", board_skipped_ms());
    at = append_pair(at, end, "watchdog_looks", board_watchdog_looks());
    at = append_pair(at, end, "watchdog_stalls", board_watchdog_stalls());
    at = append_pair(at, end, "main_max_gap_us", main_max_gap_us);
#endif
#ifdef UG_LINK_TAP
    at = append_pair(at, end, "tap_setpoints", tap.setpoints);
    at = append_pair(at, end, "max_setpoint_code", tap.max_code);
    at = append_pair(at, end, "setpoints_above_limit", tap.above);
    at = append_pair(at, end, "limit_code", tap.limit_code);
#endif
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

#ifdef UG_BOARD_QEMU
/* The raw reading behind the last CLOCK reply's place in its block (board_last_clock_read), one line each: a test
   checks the reply against the board's own clock with it (tests/test_firmware_qemu.py). */
static void console_clock_read(void)
{
    board_clock_read_t read;
    board_last_clock_read(&read);
    if (read.reads == clock_reads_told) {
        return;
    }
    clock_reads_told = read.reads;
    char line[120];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, "ev clock_read");
    at = append_pair(at, end, "reads", read.reads);
    at = append_pair(at, end, "ticks", read.ticks);
    at = append_pair(at, end, "due", read.due);
    at = append_pair(at, end, "blocks", read.blocks);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}
#endif

/* ---- start-up and the main loop --------------------------------------------------------------------- */
_Static_assert(UG_RESET_POWER_ON == UG_RESTART_POWER_ON && UG_RESET_WATCHDOG == UG_RESTART_WATCHDOG &&
               UG_RESET_FAULT == UG_RESTART_FAULT && UG_RESET_SOFTWARE == UG_RESTART_SOFTWARE &&
               UG_RESET_PIN == UG_RESTART_PIN && UG_RESET_REASONS == UG_RESTART_REASONS,
               "the reset record's reasons go on the wire as HELLO_REPLY's restart codes");

void port_configure(ug_config *config, float *um_pp_per_code)
{
    ug_config_defaults(config);
    config->sample_rate_hz = BOARD_DRIVE_RATE_HZ;
    config->dac_oversample = BOARD_OVERSAMPLE;
    config->sense_delay_samples = BOARD_BLOCK_DRIVE;
    config->sensors = UG_SENSOR_AMPLITUDE;
    config->sensor_rate_hz = 1000u;
    config->features = UG_FEATURE_AMPLITUDE_LOOP;
    config->sim_faults = 0u;
    config->link_bytes_per_s = BOARD_LINK_BYTES_PER_S;
    config->reset_stated = 1u; /* board_init read the reset record: the next HELLO says why this start */
    config->reset_reason = (uint8_t)board_reset_reason();
    config->reset_detail = board_reset_record()->detail; /* 0 after a power-on, unless told from RAM (ug_safety.h) */
#ifdef UG_BOARD_QEMU
    config->link_bytes_per_s = BOARD_QEMU_LINK_BYTES_PER_S;
    static const char name[] = "ultraglide " BOARD_NAME " (QEMU)";
    const volatile ug_emulation_config_t *e = &ug_emulation;
    config->resonance_hz = e->profile_resonance_hz;
    config->q = e->profile_q;
    config->full_scale_um_pp = e->full_scale_um_pp;
    config->max_amplitude_um_pp = e->max_amplitude_um_pp;
    config->max_drive_um_pp = e->max_drive_um_pp;
    config->carrier_min_hz = e->carrier_min_hz;
    config->carrier_max_hz = e->carrier_max_hz;
    float carrier_hz = e->profile_resonance_hz;
    config->carrier_hz = carrier_hz < e->carrier_min_hz ? e->carrier_min_hz
                                                        : (carrier_hz > e->carrier_max_hz ? e->carrier_max_hz : carrier_hz);
    *um_pp_per_code = QEMU_SENSE_SPAN * e->full_scale_um_pp / 4096.0f;
    board_emulate_plate(e->resonance_hz, e->q, e->drift_hz_per_s, e->full_scale_um_pp, *um_pp_per_code);
#ifdef UG_LINK_TAP
    ug_ring_init(&tap_ring);
    ug_tap_init(&tap, (uint16_t)(e->max_amplitude_um_pp / e->full_scale_um_pp * 65535.0f + 0.5f));
#endif
#else
    static const char name[] = "ultraglide " BOARD_NAME;
    *um_pp_per_code = BOARD_SENSE_UM_PP_PER_CODE;
#endif
    for (size_t i = 0; i < sizeof name; i++) {
        config->name[i] = name[i];
    }
}

static void boot_line(const ug_config *config, int result)
{
    char line[480];
    char *end = line + sizeof line;
    char *at = ug_append_text(line, end, result == UG_OK ? "ev boot board=" BOARD_NAME : "ev error what=config");
    at = ug_append_text(at, end, " variant=" UG_VARIANT_NAME);
#ifdef UG_BOARD_QEMU
    if (ug_emulation.magic != UG_EMULATION_MAGIC) {
        at = ug_append_text(at, end, " emulation=missing");
    }
    at = append_pair(at, end, "plate_resonance_hz", (uint32_t)(ug_emulation.resonance_hz + 0.5f));
    at = append_pair(at, end, "plate_q", (uint32_t)(ug_emulation.q + 0.5f));
#endif
#ifdef UG_LINK_TAP
    at = append_pair(at, end, "limit_code", tap.limit_code);
#endif
    at = ug_append_text(at, end, " watchdog=" BOARD_WATCHDOG_NAME);  /* board.h: what refreshes on both marks */
    at = append_pair(at, end, "watchdog_us", BOARD_WATCHDOG_US);
    const ug_reset_record_t *record = board_reset_record();
    at = ug_append_text(at, end, " reset_reason=");
    at = ug_append_text(at, end, ug_reset_name(board_reset_reason()));
    if (board_reset_reason() == UG_RESET_FAULT) {
        at = append_pair(at, end, "fault_status", record->detail);  /* CFSR */
    } else if (board_reset_reason() == UG_RESET_WATCHDOG && record->magic == UG_RESET_MAGIC) {
        at = append_pair(at, end, "marks_seen", record->detail & 3u);  /* 1 block, 2 main loop */
        at = append_pair(at, end, "looks_missed", (record->detail >> 8) & 0xFFu);
        at = append_pair(at, end, "stalls", record->detail >> 16);
        at = append_pair(at, end, "pc", record->where);
    } else if (record->detail & UG_RESET_DETAIL_FROM_RAM) {
        at = ug_append_text(at, end, " reset_from=ram");  /* no reset-cause register: the RAM kept or not */
    }
    if (record->injected != 0u) {
        at = ug_append_text(at, end, " injected=");
        at = ug_append_text(at, end, ug_inject_name(record->injected));
        if (record->silent_after_us != UG_NOT_INJECTED) {
            at = append_pair(at, end, "silent_after_us", record->silent_after_us);
        }
    }
    at = append_fixed_pair(at, end, "resonance_hz", config->resonance_hz, 1u);
    at = append_fixed_pair(at, end, "q", config->q, 1u);
    at = append_fixed_pair(at, end, "full_scale_um_pp", config->full_scale_um_pp, 3u);
    at = append_fixed_pair(at, end, "max_amplitude_um_pp", config->max_amplitude_um_pp, 3u);
    at = append_fixed_pair(at, end, "max_drive_um_pp", config->max_drive_um_pp, 3u);
    at = append_pair(at, end, "sample_rate_hz", config->sample_rate_hz);
    at = append_pair(at, end, "dac_rate_hz", BOARD_DAC_RATE_HZ);
    (void)ug_append_text(at, end, "\n");
    board_console_write(line);
}

int port_start(const ug_config *config, float um_pp_per_code)
{
    int result = ug_core_init(&core, config, NULL);
    boot_line(config, result);
    if (result != UG_OK) {
        return result;
    }
    ug_sense_init(&sense, (float)BOARD_DAC_RATE_HZ, um_pp_per_code, 2048.0f);
    sensed_carrier_hz = config->carrier_hz;
    ug_sense_set_carrier(&sense, sensed_carrier_hz);
    last_stats = board_millis();
    return UG_OK;
}

bool port_service(void)
{
    ug_marks_main();
    uint32_t now_us = board_time_us();
    if (main_last_us != 0u && now_us - main_last_us > main_max_gap_us && now_us - main_last_us < 1000000u) {
        main_max_gap_us = now_us - main_last_us;
    }
    main_last_us = now_us;
#ifdef UG_BOARD_QEMU
    uint32_t injected = board_injected_fault();
    if (injected == UG_INJECT_MAIN_HANG || injected == UG_INJECT_STACK_OVERFLOW || injected == UG_INJECT_HARD_FAULT) {
        board_inject_now(injected);  /* the main loop's faults happen here */
    }
#endif
    board_link_service();
#ifdef UG_BOARD_QEMU
    board_run_due_blocks();
#endif
    ug_core_poll(&core);
    board_link_service();
    ug_event event;
    while (ug_core_next_event(&core, &event)) {
        console_event(&event);
    }
#ifdef UG_BOARD_QEMU
    console_clock_read();
#endif
    bool more = false;
#ifdef UG_LINK_TAP
    uint8_t bytes[64];
    size_t n = 0;
    while (n < sizeof bytes && ug_ring_get(&tap_ring, &bytes[n])) {
        n++;
    }
    ug_tap_feed(&tap, bytes, n);
    more = n == sizeof bytes;
#endif
    if (board_millis() - last_stats >= 1000u) {
        last_stats += 1000u;
        console_stats();
    }
    return more;
}

bool port_take_work(void)
{
    bool was = work != 0u;
    work = 0u;
    return was;
}
