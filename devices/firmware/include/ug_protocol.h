/*
 * ug_protocol.h - the wire protocol's numbers (docs/protocol.md, version 3). The host's copy is
 * devices/protocol/__init__.py; tests/test_firmware_core.py checks the two against each other.
 */
#ifndef UG_PROTOCOL_H
#define UG_PROTOCOL_H

#define UG_PROTOCOL_VERSION 3u
#define UG_LOWEST_VERSION 2u
#define UG_MAX_BODY 1024u      /* decoded bytes: type, seq, payload, CRC */
#define UG_MAX_ENCODED 1030u   /* MAX_BODY + ceil(MAX_BODY / 254) + 1 */
#define UG_MIN_BODY 7u         /* type, seq, CRC */
#define UG_SETPOINT_SCALE 65535u
#define UG_MAX_SETPOINTS_PER_FRAME 240u
#define UG_TELEMETRY_HZ 50u
#define UG_WATCHDOG_MS 100u
#define UG_WATCHDOG_RAMP_MS 20u
#define UG_BUFFER_MS 250u
#define UG_PREFILL_MS 10u
#define UG_TRIP_MARGIN 0.01f
#define UG_OVER_LIMIT_REARM 0.98f
#define UG_SENSORS_PERIOD_MS 10u
#define UG_SENSORS_REST_PERIOD_MS 50u
#define UG_MIN_SENSOR_RATE_HZ 1000u
#define UG_MAX_SENSOR_SAMPLES 80u
#define UG_MAX_NAME_BYTES 64u
#define UG_NOT_PLAYING 0xFFFFFFFFu
#define UG_MAX_SIM_FAULT_MS 5000u

/* host -> device */
#define UG_HELLO 0x01u
#define UG_SET_CARRIER 0x02u
#define UG_ENABLE 0x03u
#define UG_SETPOINTS 0x04u
#define UG_HEARTBEAT 0x05u
#define UG_CLEAR_FAULTS 0x06u
#define UG_SET_LOOP 0x07u
#define UG_SETPOINTS_FORCE 0x08u
#define UG_CLOCK 0x09u /* v3, UG_FEATURE_CLOCK_STATED: answered at once with CLOCK_REPLY */
#define UG_SIM_FAULT 0x7Eu
/* device -> host */
#define UG_HELLO_REPLY 0x81u
#define UG_ACK 0x82u
#define UG_NAK 0x83u
#define UG_TELEMETRY 0x90u
#define UG_SENSORS 0x91u
#define UG_CLOCK_REPLY 0x92u

/* NAK reasons, checked in this order */
#define UG_NAK_UNKNOWN_TYPE 1u
#define UG_NAK_UNSUPPORTED 4u
#define UG_NAK_BAD_LENGTH 2u
#define UG_NAK_BAD_VALUE 3u
#define UG_NAK_INTERNAL 5u

/* fault bits */
#define UG_FAULT_WATCHDOG 0x0001u
#define UG_FAULT_TRIP 0x0002u
#define UG_FAULT_OVER_LIMIT 0x0004u
#define UG_FAULT_OVERRUN 0x0008u
#define UG_FAULT_UNDERRUN 0x0010u
#define UG_FAULT_BAD_COMMAND 0x0020u
#define UG_FAULT_OVERHEAT 0x0040u
#define UG_FAULT_BITS 8u

/* HELLO_REPLY v3 */
#define UG_SENSOR_AMPLITUDE 0x01u
#define UG_SENSOR_NORMAL_FORCE 0x02u
#define UG_SENSOR_LATERAL_FORCE 0x04u
#define UG_FEATURE_AMPLITUDE_LOOP 0x01u
#define UG_FEATURE_BRAKING 0x02u /* the amplitude loop brakes: an antiphase drive, down to minus the limit */
#define UG_FEATURE_FORCE_CORRECTION 0x04u /* SETPOINTS_FORCE: values rescaled by the force measured at play */
#define UG_FEATURE_LINK_STATED 0x08u /* HELLO_REPLY goes on with link_bytes_per_s:u32 and q:f32 before the name
                                        (set by the core when ug_config.link_bytes_per_s is not 0) */
#define UG_FEATURE_RESET_STATED 0x10u /* HELLO_REPLY goes on (after the link's fields, if any) with
                                         restart_reason:u8 and restart_detail:u32 before the name: why the board
                                         last started (set by the core when ug_config.reset_stated is 1) */
#define UG_FEATURE_CLOCK_STATED 0x20u /* CLOCK is answered at once with CLOCK_REPLY: the device's sensor clock when it
                                         took the request (set by the core in a v3 session on a device with sensors) */
#define UG_MAX_CLOCK_LAG_MS 1u /* CLOCK_REPLY's clock is never ahead of the device's when it took the request, and at
                                  most this far behind (a board that cannot read its ADC's position within a block) */

/* HELLO_REPLY's restart_reason (UG_FEATURE_RESET_STATED): why the board last started */
#define UG_RESTART_POWER_ON 0u /* power applied, or no record of anything else */
#define UG_RESTART_WATCHDOG 1u /* its hardware watchdog (or the emulator's stand-in) expired: detail says which mark
                                  was missing (bits 0-1: the marks seen, 1 the block interrupt's, 2 the main loop's) */
#define UG_RESTART_FAULT 2u    /* a fault handler reset it: detail is the fault's status (Cortex-M: CFSR) */
#define UG_RESTART_SOFTWARE 3u /* the firmware asked for a reset */
#define UG_RESTART_PIN 4u      /* the reset pin */
#define UG_RESTART_REASONS 5u

/* SIM_FAULT kinds */
#define UG_SIM_DROP 1u
#define UG_SIM_CORRUPT 2u
#define UG_SIM_HANG 3u
#define UG_SIM_DISCONNECT 4u
#define UG_SIM_OVERHEAT 5u

/* TELEMETRY.playback: the output's state (docs/protocol.md, "State machine") */
#define UG_OFF 0u
#define UG_PREFILL 1u
#define UG_PLAYING 2u
#define UG_DRY 3u
#define UG_RAMP 4u

/* payload sizes (v3; v2's HELLO_REPLY 33 and TELEMETRY 71) */
#define UG_HELLO_REPLY_V2_SIZE 33u
#define UG_HELLO_REPLY_V3_SIZE 41u
#define UG_HELLO_REPLY_LINK_SIZE 49u /* v3's, with UG_FEATURE_LINK_STATED's two fields */
#define UG_HELLO_RESET_SIZE 5u /* UG_FEATURE_RESET_STATED's two fields */
#define UG_TELEMETRY_V2_SIZE 71u
#define UG_TELEMETRY_V3_SIZE 89u
#define UG_SENSORS_HEADER_SIZE 9u
#define UG_SENSOR_SAMPLE_SIZE 12u
#define UG_CLOCK_REPLY_SIZE 8u /* asked_seq:u16, sample:u32, fraction:u16 */
#define UG_SETPOINTS_HEADER_SIZE 10u
#define UG_SETPOINTS_FORCE_HEADER_SIZE 20u
#define UG_MAX_FORCE_EXPONENT 2.0f
#define UG_MAX_REFERENCE_FORCE_N 20.0f
#define UG_FORCE_SPAN 2.0f /* readings within force_n / SPAN .. SPAN x force_n are corrected */

#endif /* UG_PROTOCOL_H */
