/*
 * ug_core.h - ultraglide's portable plate-driver firmware core: its configuration, its API, its state.
 *
 * One ug_core holds everything the firmware keeps (about 36 KB, no dynamic allocation): the frame
 * decoder, the protocol state machine of docs/protocol.md, the jitter buffer, the watchdog, the
 * device-side limiter, faults and counters, telemetry and SENSORS frames, the carrier's DDS and the
 * amplitude loop. A port (see ug_port.h) allocates one statically, calls ug_core_init() with a
 * ug_config, and then feeds it bytes, ticks, and DAC/ADC blocks.
 *
 *     static ug_core core;
 *     ug_config config;
 *     ug_config_defaults(&config);              the reference values (sim-plate: 25 kHz, Q 200, 8/6 um)
 *     config.full_scale_um_pp = 10.0f;          ... the board's own
 *     if (ug_core_init(&core, &config, &board) != UG_OK) halt();
 *
 * The fields of struct ug_core are the core's private state: a port reads them only through
 * ug_core_status() and ug_core_next_event().
 */
#ifndef UG_CORE_H
#define UG_CORE_H

#include <stdbool.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "ug_port.h"
#include "ug_protocol.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- sizes (compile-time: the core allocates nothing) -------------------------------------------- */
#ifndef UG_BUFFER_CAPACITY
#define UG_BUFFER_CAPACITY 12000u /* setpoint values: 250 ms at 48 kHz */
#endif
#ifndef UG_RX_RING
#define UG_RX_RING 2048u /* bytes from the UART not yet decoded (a power of two) */
#endif
#ifndef UG_TX_RING
#define UG_TX_RING 4096u /* bytes for the UART not yet sent (a power of two) */
#endif
#define UG_MAX_BLOCK 512u    /* drive samples in one ug_core_dac_block() or ug_core_drive_block() call */
#define UG_EVENTS 64u        /* events kept for the port to read (a power of two) */
#define UG_HISTORY 256u      /* drive samples of loop history (sense_delay_samples < this; a power of two) */
#define UG_JUMPS 32u         /* index jumps (lost, overrun) marked in the buffer (a power of two) */
#define UG_OUTBOX 2u          /* replies one frame may queue (it gives one; a broken build may give two) */
#define UG_OUTBOX_PAYLOAD 116u /* HELLO_REPLY v3 with its link fields (49 bytes) and a 64-byte name, the longest */
#define UG_FORCE_MARKS 32u   /* force references marked in the buffer (SETPOINTS_FORCE; a power of two) */

/* ---- configuration --------------------------------------------------------------------------------- */
typedef struct ug_config {
    float resonance_hz;        /* the plate's nominal resonance (HELLO_REPLY) */
    float q;                   /* its nominal quality factor: tau = q / (pi resonance_hz) */
    float full_scale_um_pp;    /* steady amplitude at full-scale drive at resonance */
    float max_amplitude_um_pp; /* the plate's safe limit, enforced here */
    float max_drive_um_pp;     /* overdrive ceiling (max_amplitude_um_pp .. full_scale_um_pp) */
    float carrier_min_hz, carrier_max_hz;
    float carrier_hz;          /* at power-up */
    uint32_t min_setpoint_rate_hz, max_setpoint_rate_hz;
    uint16_t watchdog_ms;      /* 20..1000 */
    uint16_t buffer_ms;        /* 50..1000, and buffer_ms x max rate / 1000 <= UG_BUFFER_CAPACITY */
    uint32_t sample_rate_hz;   /* drive samples a second (>= max_setpoint_rate_hz; a multiple of 1000) */
    uint16_t dac_oversample;   /* carrier samples per drive sample in ug_core_dac_block (1..16) */
    uint8_t sensors;           /* UG_SENSOR_* bits this board has */
    uint16_t sensor_rate_hz;   /* sensor samples a second (>= 1000 with any sensor; divides sample_rate_hz) */
    uint8_t features;          /* UG_FEATURE_* bits (the amplitude loop needs UG_SENSOR_AMPLITUDE, braking the loop) */
    uint8_t max_version;       /* the highest protocol version spoken: 3, or 2 */
    uint8_t sim_faults;        /* 1: SIM_FAULT accepted (the simulator); 0: NAK 4 (real firmware) */
    uint16_t sense_delay_samples; /* ADC block lag behind the drive block, samples (< UG_HISTORY) */
    uint32_t link_bytes_per_s; /* what the host link carries to the board, sustained, bytes/s (HELLO_REPLY v3, with
                                  UG_FEATURE_LINK_STATED; the host fits its stream to it); 0: not stated */
    uint8_t reset_stated;      /* 1: HELLO_REPLY v3 says why the board last started (UG_FEATURE_RESET_STATED) */
    uint8_t reset_reason;      /* UG_RESTART_* (the port reads its reset record at boot, before ug_core_init) */
    uint32_t reset_detail;     /* the watchdog's marks seen, or the fault's status; 0 otherwise */
    char name[UG_MAX_NAME_BYTES + 1]; /* UTF-8, NUL-terminated here (not on the wire) */
} ug_config;

enum { UG_OK = 0, UG_BAD_CONFIG = -1 };

/* ---- what the core tells a port (ug_core_status) ----------------------------------------------------- */
typedef struct ug_status {
    uint8_t enabled, playback, loop, session_version;
    uint16_t faults;
    uint16_t buffered;
    uint32_t stream_rate_hz;   /* 0: no stream */
    uint32_t expected_index;   /* valid while stream_rate_hz != 0 */
    float carrier_hz;
    float drive;               /* the drive now, fraction of full scale, after limiter and loop */
    float measured_um_pp;      /* the most recent measured amplitude */
    uint32_t frames_ok, crc_errors, framing_errors;
    uint32_t setpoints, lost_setpoints, late_setpoints, discarded_setpoints, overrun_setpoints;
    uint32_t fault_counts[UG_FAULT_BITS];
    uint32_t naks, rx_overflows, tx_dropped, events_dropped;
    uint32_t now_ms;           /* ticks since power-up */
    uint32_t next_telemetry_ms; /* the tick at which the next TELEMETRY frame is due */
    uint64_t samples;          /* drive samples produced since power-up */
    uint8_t stage_hot;
    uint32_t lost_ms;          /* block time the port reported lost (ug_core_lost_time), ms */
} ug_status;

/* ---- events: what happened, for a port to log (the simulator prints them) --------------------------- */
enum ug_event_kind {
    UG_EV_HELLO = 1,       /* a: the host's version, b: the session's */
    UG_EV_CARRIER,         /* value: Hz */
    UG_EV_ENABLED,
    UG_EV_DISABLED,        /* a: UG_WHY_* */
    UG_EV_STREAM_STARTED,  /* value: rate, Hz */
    UG_EV_STREAM_STOPPED,  /* no SETPOINTS for 50 ms, or the output went off */
    UG_EV_FAULT,           /* a: fault bit index; value: measured um p-p (over-limit, trip); b: command << 8 | reason
                              (bad-command) */
    UG_EV_LOOP,            /* a: mode */
    UG_EV_SIM_FAULT        /* a: kind, b: duration, ms */
};
enum { UG_WHY_HOST = 1, UG_WHY_TRIP, UG_WHY_OVERHEAT, UG_WHY_HELLO };

typedef struct ug_event {
    uint64_t sample;       /* the drive sample count when it happened */
    uint32_t time_ms;      /* the tick count when it happened */
    uint8_t kind, a;
    uint16_t b;
    float value;
} ug_event;

/* ---- conformance breaks (the simulator's build only: -DUG_CONFORMANCE_BREAKS=1) ------------------- */
/* Each breaks the rule of docs/protocol.md with the same identifier, for testing `plate check`. */
enum ug_break {
    UG_BREAK_FRAMING, UG_BREAK_CRC, UG_BREAK_DEVICE_SEQ, UG_BREAK_SEQ_ECHO, UG_BREAK_VERSION,
    UG_BREAK_HELLO_NO_STATE, UG_BREAK_NAK_ORDER, UG_BREAK_NAK_NO_EFFECT, UG_BREAK_ACK, UG_BREAK_CARRIER,
    UG_BREAK_TELEMETRY, UG_BREAK_SENSORS, UG_BREAK_RATE, UG_BREAK_EXPECTED, UG_BREAK_OVERRUN,
    UG_BREAK_PREFILL, UG_BREAK_UNDERRUN, UG_BREAK_DISCARD, UG_BREAK_ENABLE, UG_BREAK_LIMIT,
    UG_BREAK_OVER_LIMIT, UG_BREAK_WATCHDOG, UG_BREAK_FAULT_LATCH, UG_BREAK_FAULT_COUNT,
    UG_BREAK_CLEAR_FAULTS, UG_BREAK_LOOP, UG_BREAK_CLOCK, UG_BREAKS
};
/* "R-FRAMING", ... in enum order; NULL past the end */
const char *ug_break_rule(unsigned which);

/* ---- the core's state (private: read it through ug_core_status) ------------------------------------ */
typedef struct ug_decoder {
    uint8_t body[UG_MAX_BODY];
    uint16_t length;       /* decoded bytes so far (beyond UG_MAX_BODY: counted, not kept) */
    uint16_t encoded;      /* encoded bytes of this run */
    uint8_t code, left;    /* COBS: the current block's code and bytes left in it */
    uint8_t discarding;    /* an over-long run: drop up to the next 0x00 */
    uint8_t bad;           /* this run is not valid COBS */
} ug_decoder;

typedef struct ug_core {
    ug_config config;
    void *port;
    uint32_t breaks;       /* (1 << UG_BREAK_*): only with UG_CONFORMANCE_BREAKS */

    /* derived from the configuration */
    float limit_fraction, drive_ceiling, trip_um_pp, rearm_um_pp;
    float fast_gain;       /* the fastest plausible plate's per-sample envelope gain (tau / 2) */
    float fast_delay_decay; /* that plate's decay over the measurement's lag, (1 - fast_gain)^sense_delay_samples */
    float model_decay;     /* the nominal plate's per-sample envelope decay exp(-1 / (fs tau)) */
    uint32_t telemetry_period_ms;

    /* link */
    /* single-producer single-consumer rings: the producer stores its bytes, then publishes its index with release;
       the consumer reads that index with acquire before the bytes (C11 atomics) */
    _Atomic uint16_t rx_head, rx_tail;
    uint8_t rx[UG_RX_RING];
    _Atomic uint16_t tx_head, tx_tail;
    uint8_t tx[UG_TX_RING];
    ug_decoder decoder;
    uint16_t seq;          /* the device's next seq */
    uint8_t session;       /* the negotiated version */

    /* time */
    volatile uint32_t now_ms;
    uint64_t samples;
    uint32_t last_frame_ms; /* the last valid frame, for the watchdog */
    uint32_t last_setpoints_ms;
    uint32_t telemetry_due_ms, sensors_due_ms;
    volatile uint8_t telemetry_due, sensors_due;

    /* output state machine */
    uint8_t state, streaming, watchdog_fired, over_armed, stage_hot, loop_mode;
    uint32_t hot_until_ms;
    uint32_t rate;          /* 0: no stream */
    uint32_t expected;
    uint8_t have_expected;
    uint64_t step;          /* playback phase step per drive sample, 2^32 x rate / sample_rate (2^32 at rate = sample_rate) */
    uint32_t phase;         /* playback phase within the current value */
    uint16_t prefill;       /* values that start playback */
    uint16_t capacity;      /* values the buffer holds at this rate */
    uint16_t buf[UG_BUFFER_CAPACITY];
    uint16_t buf_head, buf_count;
    uint32_t buf_epoch;     /* counts the buffer's clears (block interrupt or main loop) */
    /* a SETPOINTS frame's codes copied into the buffer's free room before its critical section (main loop only):
       where, how many, from which bytes, in which epoch; the push in the section only commits them */
    const uint8_t *staged_codes;
    uint16_t staged_at, staged_n;
    uint32_t staged_epoch;
    uint32_t popped;        /* values taken from the buffer, ever */
    uint32_t play_index;    /* the stream index of the value playing */
    uint32_t next_pop_index; /* ... of the value at the buffer's head */
    uint32_t tail_index;    /* ... the next value pushed would have, if contiguous */
    struct { uint32_t at, jump; } jumps[UG_JUMPS]; /* at the popped-th value, the index jumps by jump */
    uint8_t jump_head, jump_count;
    float current, next;    /* the value playing and the one after (fractions), for interpolation */
    float hold;             /* the value held while dry */
    float drive;            /* the drive now (after limiter, loop and ramp) */
    float ramp_from;        /* the watchdog ramp's start */
    uint32_t ramp_samples, ramp_left;
    float fast_plate;       /* the fastest plausible plate's envelope, fraction */
    float measured;         /* the last measured amplitude, fraction of full scale */
    float measured_um_pp;

    /* amplitude loop */
    float loop_model, loop_integral, loop_approach;
    uint8_t loop_saturated;
    float hist_model[UG_HISTORY], hist_target[UG_HISTORY];
    uint32_t hist_index[UG_HISTORY]; /* the stream index playing at each drive sample (or UG_NOT_PLAYING) */
    uint16_t hist_head;
    /* braking (UG_FEATURE_BRAKING): the fastest plausible plate's envelope (signed: the drive's phase), reset
       to each measurement, and its decay over a loop period; the phase check: the previous measurement, whether
       the drive pushed or braked since (and in the block before), the brake held off */
    float brake_plate, brake_period_decay, brake_last;
    uint8_t brake_pushed, brake_braked, brake_prev_pushed, brake_inhibit;
    float hist_brake[UG_HISTORY];

    /* force correction (ug_force.c): the buffer's references, the one playing, the force now */
    struct { uint32_t at; float force_n, exponent, limit; } force_marks[UG_FORCE_MARKS];
    uint8_t force_mark_head, force_mark_count;
    float force_tail_ref_n, force_tail_exponent, force_tail_limit; /* the last marked */
    float force_ref_n, force_exponent, force_limit; /* the value playing's: F_h (N), e (0: none), limit fraction */
    float force_now_n;      /* the normal force over the last ADC block, N (NaN: none) */
    float force_gain;       /* (force_now_n / force_ref_n)^force_exponent, or 1 */

    /* carrier DDS */
    uint32_t carrier_phase, carrier_step;
    float carrier_hz;
    float dac_last;         /* the drive at the end of the previous DAC block */
    float scratch[UG_MAX_BLOCK];

    /* sensors */
    uint32_t sensor_decimation, sensor_count_in; /* drive samples per sensor sample, and so far */
    float sensor_sum[3];
    uint32_t sensor_first_index;
    uint32_t sensor_next;    /* the number the next sensor sample will have */
    /* two rings: the block interrupt fills sensor_ring[sensor_active]; the main loop swaps them under its lock (a few
       instructions) and encodes the other one outside it */
    struct { float value[3]; uint32_t index; } sensor_ring[2][UG_MAX_SENSOR_SAMPLES];
    uint8_t sensor_pending, sensor_active;

    /* counters */
    uint32_t frames_ok, crc_errors, framing_errors;
    uint32_t setpoints, lost, late, discarded, overrun;
    uint32_t fault_counts[UG_FAULT_BITS];
    uint16_t faults;
    uint32_t naks, rx_overflows, tx_dropped;
    uint32_t lost_ms;

    /* events */
    ug_event events[UG_EVENTS];
    uint16_t event_head, event_count;
    uint32_t events_dropped;

    /* replies (ACK, NAK, HELLO_REPLY) decided inside a frame's critical section, encoded after it (main loop only) */
    uint8_t outbox_deferring, outbox_count;
    struct { uint8_t type; uint8_t length; uint8_t payload[UG_OUTBOX_PAYLOAD]; } outbox[UG_OUTBOX];

    /* a frame being built for the host (main loop only) */
    uint8_t scratch_payload[UG_MAX_BODY];
    uint8_t scratch_body[UG_MAX_BODY];
    uint8_t frame[UG_MAX_ENCODED + 8];
} ug_core;

/* ---- the API (contexts: see ug_port.h) ------------------------------------------------------------- */
void ug_config_defaults(ug_config *config);
int ug_core_init(ug_core *core, const ug_config *config, void *port);

void ug_core_uart_rx(ug_core *core, const uint8_t *data, size_t n);
size_t ug_core_uart_tx(ug_core *core, uint8_t *out, size_t max);
void ug_core_poll(ug_core *core);
void ug_core_tick(ug_core *core);
void ug_core_drive_block(ug_core *core, float *drive, size_t n);
void ug_core_dac_block(ug_core *core, int16_t *out, size_t n_dac);
size_t ug_core_adc_block(ug_core *core, const float *amplitude_um_pp, const float *normal_force_n,
                         const float *lateral_force_n, size_t n);
void ug_core_set_stage_hot(ug_core *core, bool hot);
/* One block, the port's one call per block interrupt: ug_core_adc_block (what the ADC measured, n drive samples),
   ug_core_dac_block (the next n_dac carrier samples into dac), ug_core_tick, in that order; returns what
   ug_core_adc_block returns (n: nothing cut; less: the output went off at that sample, and the port silences the
   half playing now, as ug_port_output_safe asks). */
size_t ug_core_block(ug_core *core, const float *amplitude_um_pp, const float *normal_force_n,
                     const float *lateral_force_n, size_t n, int16_t *dac, size_t n_dac);
/* Blocks the port could not run (its block interrupt came late: both halves had played): ms of the core's clock
   pass without output (the watchdog, the fault timers and the telemetry schedule keep their time), counted in
   ug_status.lost_ms. The port has silenced the DAC itself: nothing stale plays. */
void ug_core_lost_time(ug_core *core, uint32_t ms);

void ug_core_status(const ug_core *core, ug_status *out);
bool ug_core_next_event(ug_core *core, ug_event *out);
/* room in the receive ring, bytes (the simulator feeds no more than this before polling) */
size_t ug_core_rx_room(const ug_core *core);

/* conformance breaks: a bit mask of (1 << UG_BREAK_*); refused (returns false) unless built with them */
bool ug_core_set_breaks(ug_core *core, uint32_t breaks);

/* the frame layer, for ports and tests */
uint32_t ug_crc32(const uint8_t *data, size_t n);
size_t ug_cobs_encode(const uint8_t *in, size_t n, uint8_t *out); /* out: n + n / 254 + 1 bytes */

#ifdef __cplusplus
}
#endif

#endif /* UG_CORE_H */
