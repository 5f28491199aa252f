"""Protocol v3's numbers and codes, as docs/protocol.md names them (a test checks the two against each other).

Limits and timings (ms, Hz, bytes), the command and reply types, sensor and feature bits, playback states,
NAK reasons, fault bits and their words, the simulator's fault kinds; and the host's frame period for a link.
Everything here is re-exported by :mod:`ultraglide.devices.protocol`.
"""

from __future__ import annotations

PROTOCOL_VERSION = 3  # the version docs/protocol.md describes, and the highest ultraglide speaks
SUPPORTED_VERSIONS = (2, 3)
MAX_BODY = 1024  # bytes of a decoded frame (type, seq, payload, CRC)
MAX_ENCODED = 1030  # MAX_BODY + ceil(MAX_BODY / 254) + 1: a longer run without a 0x00 is dropped
SETPOINT_SCALE = 65535  # a setpoint of 65535 is the plate's full-scale drive (or, with the loop on, amplitude)
MAX_SETPOINTS_PER_FRAME = 240
FAST_BATCH_S = 0.001  # the host sends one SETPOINTS frame every 1 ms where the link has room (batch_s_for)
BATCH_S = 0.002  # and every 2 ms where it has not: fewer frames, less framing overhead
FRAME_OVERHEAD_BYTES = 19  # a SETPOINTS frame of n <= 118 values is 19 + 2n bytes on the wire
LINK_MARGIN = 0.5  # the stream the host chooses takes at most this fraction of what the device's link carries
TELEMETRY_HZ = 50
TELEMETRY_TOLERANCE = 0.1  # the telemetry rate a device keeps, within ±10 % of TELEMETRY_HZ over a second
WATCHDOG_MS = 100  # no valid frame for this long while enabled: the device ramps to zero
WATCHDOG_LATE_MS = 10  # ... and fires at most this much after watchdog_ms
WATCHDOG_RAMP_MS = 20
BUFFER_MS = 250  # setpoints beyond this much playing time are dropped (overrun)
PREFILL_MS = 10  # the device plays once ceil(PREFILL_MS * rate / 1000) values are buffered (jitter buffer)
ACK_DEADLINE_MS = 50  # the device answers a command within this long
HOST_ACK_TIMEOUT_S = 2.0  # the host gives up on an answer after this long
HOST_SILENCE_MS = 500  # no telemetry for this long: the host treats the device as gone
MAX_SIM_FAULT_MS = 5000
TRIP_MARGIN = 0.01  # the device trips above max_amplitude_um_pp × (1 + margin)
OVER_LIMIT_REARM = 0.98  # over-limit is raised again only after the amplitude fell below this × the limit
SENSORS_PERIOD_MS = 10  # a SENSORS frame at least this often while the output is enabled
SENSORS_REST_PERIOD_MS = 50  # ... and at least this often while it is disabled
MIN_SENSOR_RATE_HZ = 1000  # sensor samples a second, at least, on a device that has a sensor
MAX_SENSOR_SAMPLES = 80  # samples in one SENSORS frame, at most
MAX_NAME_BYTES = 64  # the device's name in HELLO_REPLY, UTF-8, at most
NOT_PLAYING = 0xFFFFFFFF  # SENSORS.setpoint_index while no stream value plays
MAX_CLOCK_LAG_MS = 1  # CLOCK_REPLY's clock: never ahead of the device's when it took the request, at most this behind


def batch_s_for(baud: int, rate_hz: int) -> float:
    """The host's frame period (s): 1 ms where a stream of ``rate_hz`` setpoints/s in 1 ms frames takes at most
    half of a ``baud`` link (8N1, ten bits a byte), so a touch waits less for the next frame; else 2 ms."""
    fast_bytes_per_s = FRAME_OVERHEAD_BYTES / FAST_BATCH_S + 2 * rate_hz
    return FAST_BATCH_S if fast_bytes_per_s <= 0.5 * baud / 10 else BATCH_S


# host → device
HELLO = 0x01
SET_CARRIER = 0x02
ENABLE = 0x03
SETPOINTS = 0x04
HEARTBEAT = 0x05
CLEAR_FAULTS = 0x06
SET_LOOP = 0x07  # v3: open loop (0) or the firmware's amplitude loop (1)
SETPOINTS_FORCE = 0x08  # v3, FEATURE_FORCE_CORRECTION: SETPOINTS whose values carry the force they assumed
CLOCK = 0x09  # v3, FEATURE_CLOCK_STATED: answered at once with CLOCK_REPLY, the device's sensor clock
SIM_FAULT = 0x7E  # simulator only: inject a fault for tests
HOST_COMMANDS = (HELLO, SET_CARRIER, ENABLE, SETPOINTS, HEARTBEAT, CLEAR_FAULTS, SET_LOOP, SETPOINTS_FORCE, CLOCK,
                 SIM_FAULT)
V3_COMMANDS = (SET_LOOP, SETPOINTS_FORCE, CLOCK)  # refused with NAK 4 in a session negotiated as v2
# device → host
HELLO_REPLY = 0x81
ACK = 0x82
NAK = 0x83
TELEMETRY = 0x90
SENSORS = 0x91  # v3: sensor samples, sent while the device has any sensor
CLOCK_REPLY = 0x92  # v3: the answer to CLOCK

# HELLO_REPLY v3: the sensors a device has (bits of ``sensors``) and what its firmware does (``features``)
SENSOR_AMPLITUDE = 1 << 0  # the vibration amplitude, from a sensing piezo
SENSOR_NORMAL_FORCE = 1 << 1
SENSOR_LATERAL_FORCE = 1 << 2
SENSOR_NAMES = {SENSOR_AMPLITUDE: "vibration amplitude", SENSOR_NORMAL_FORCE: "normal force",
                SENSOR_LATERAL_FORCE: "lateral force"}
FEATURE_AMPLITUDE_LOOP = 1 << 0  # the firmware's amplitude loop (SET_LOOP 1)
FEATURE_BRAKING = 1 << 1  # ... which brakes with an antiphase drive (down to minus the limit)
FEATURE_FORCE_CORRECTION = 1 << 2  # SETPOINTS_FORCE: values rescaled by the force measured at play
FEATURE_LINK_STATED = 1 << 3  # HELLO_REPLY goes on, before the name, with link_bytes_per_s:u32 and q:f32
FEATURE_RESET_STATED = 1 << 4  # ... and (after the link's fields, if any) restart_reason:u8, restart_detail:u32
FEATURE_CLOCK_STATED = 1 << 5  # CLOCK is answered at once with CLOCK_REPLY: the sensor clock when it took it
# HELLO_REPLY's restart_reason (FEATURE_RESET_STATED): why the board last started
RESTART_POWER_ON, RESTART_WATCHDOG, RESTART_FAULT, RESTART_SOFTWARE, RESTART_PIN = range(5)
RESTART_WORDS = {RESTART_POWER_ON: "power-on", RESTART_WATCHDOG: "its watchdog expired",
                 RESTART_FAULT: "a fault handler reset it", RESTART_SOFTWARE: "its firmware asked for a reset",
                 RESTART_PIN: "its reset pin"}
RESTART_DETAIL_FROM_RAM = 1 << 0  # after RESTART_POWER_ON or RESTART_PIN: no reset-cause register, told from its RAM
MAX_FORCE_EXPONENT = 2.0  # SETPOINTS_FORCE's exponent lies in -2..2
MAX_REFERENCE_FORCE_N = 20.0  # ... and its force in (0, 20] N
FORCE_SPAN = 2.0  # the device corrects where its force lies within force_n / 2 .. 2 force_n
LOOP_OPEN, LOOP_AMPLITUDE = 0, 1

# TELEMETRY v3: what the output is doing
PLAYBACK_OFF, PLAYBACK_PREFILL, PLAYBACK_PLAYING, PLAYBACK_DRY, PLAYBACK_RAMP = 0, 1, 2, 3, 4
PLAYBACK_NAMES = {PLAYBACK_OFF: "off", PLAYBACK_PREFILL: "prefill", PLAYBACK_PLAYING: "playing",
                  PLAYBACK_DRY: "dry", PLAYBACK_RAMP: "watchdog ramp"}

# NAK reasons
NAK_UNKNOWN_TYPE = 1  # no such command
NAK_BAD_LENGTH = 2  # the payload's length is wrong for the command
NAK_BAD_VALUE = 3  # a field is out of range (carrier, enable flag, rate, count, loop mode, fault kind)
NAK_UNSUPPORTED = 4  # a known command this device or session does not do (SIM_FAULT on firmware, v3 in v2)
NAK_INTERNAL = 5  # the device could not carry the command out (a handler failed; enabling while hot)
NAK_REASONS = {NAK_UNKNOWN_TYPE: "unknown command", NAK_BAD_LENGTH: "wrong payload length",
               NAK_BAD_VALUE: "value out of range", NAK_UNSUPPORTED: "not supported by this device",
               NAK_INTERNAL: "internal error on the device"}

# Fault bits: each latches in TELEMETRY.faults until CLEAR_FAULTS clears it; each has a counter.
FAULT_WATCHDOG = 1 << 0  # no valid frame for WATCHDOG_MS while enabled: output ramped to zero
FAULT_TRIP = 1 << 1  # measured amplitude above the plate's safe maximum: output cut, disabled
FAULT_OVER_LIMIT = 1 << 2  # measured amplitude rose above the safe maximum (by less than the trip margin)
FAULT_OVERRUN = 1 << 3  # setpoints arrived faster than they play: some were dropped
FAULT_UNDERRUN = 1 << 4  # the setpoint buffer ran dry: last value held
FAULT_BAD_COMMAND = 1 << 5  # a frame was refused with a NAK
FAULT_OVERHEAT = 1 << 6  # the driver stage is too hot: output cut, disabled
FAULT_BITS = 8  # TELEMETRY carries one counter per bit; bit 7 is reserved
FAULT_NAMES = {FAULT_WATCHDOG: "watchdog", FAULT_TRIP: "trip", FAULT_OVER_LIMIT: "over-limit",
               FAULT_OVERRUN: "overrun", FAULT_UNDERRUN: "underrun", FAULT_BAD_COMMAND: "bad-command",
               FAULT_OVERHEAT: "overheat"}
FAULT_WORDS = {
    "watchdog": "watchdog trip (no valid frame for 100 ms; output ramped to zero)",
    "trip": "over-amplitude trip (measured amplitude above the plate's limit; output cut and disabled)",
    "over-limit": "excursion above the plate's amplitude limit (within the trip margin)",
    "overrun": "buffer overrun (setpoints dropped)",
    "underrun": "buffer underrun (last value held)",
    "bad-command": "frame refused by the device (NAK)",
    "overheat": "overheat (output cut and disabled)",
}

SIM_DROP, SIM_CORRUPT, SIM_HANG, SIM_DISCONNECT, SIM_OVERHEAT = 1, 2, 3, 4, 5
SIM_FAULT_KINDS = {SIM_DROP: "drop", SIM_CORRUPT: "corrupt", SIM_HANG: "hang", SIM_DISCONNECT: "disconnect",
                   SIM_OVERHEAT: "overheat"}
