"""The serial plate driver's session: the connection's state, made explicit, and the moves between states.

A :class:`Session` connects (open, HELLO, the device's limits bound, the first telemetry, carrier, ENABLE),
sends commands and waits for their answers, rests the plate (zero setpoints, ENABLE 0) and disconnects. What
it holds is the state every other part reads: connected or not, the device and the limits that bind, whether
the output is on, cut by the device, or to be enabled again.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import serial
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.serial.handshake import Limits, bind_limits, check_device
from ultraglide.devices.serial.link import BACKOFF_S, COMMAND_NAMES, REST_ACK_S, SerialCounters
from ultraglide.devices.serial.locks import DriverLocks
from ultraglide.devices.serial.report import RunAccount
from ultraglide.devices.serial.transport import Transport


@dataclass
class SessionState:
    """What is true of the link and the plate now. Written by the session, the writer and the telemetry reader
    (each field by the parts its comment names); read by all."""

    connected: threading.Event = field(default_factory=threading.Event)
    active: bool = False  # this connection's HELLO_REPLY has arrived: its telemetry counts (session)
    device: p.HelloReply | None = None  # what the device said of itself, last handshake (session)
    output_on: bool = False  # the host enabled the output and streams setpoints (session, writer)
    enabled_at: float = 0.0  # when the last ENABLE 1 went, perf_counter s (session, writer)
    reenable: bool = False  # telemetry says the plate is off while the host streams: enable again (reader, writer)
    cut: bool = False  # the device disabled itself over this run (trip, overheat): never re-enabled (reader)
    loop_on: bool = False  # the device's amplitude loop runs, this connection (session)
    last_heard: float = 0.0  # time.monotonic() of the last frame received (reader, writer)
    first_telemetry: threading.Event | None = None  # set by the first telemetry of the run (reader)
    restarted: bool = False  # telemetry's counters began again: the device restarted, connect anew (reader, writer)
    why_restarted: bool = False  # ... and the next handshake is to say why (writer, session)
    handshakes: int = 0  # HELLO_REPLYs bound over the run (session)


class Replies:
    """The answers the session waits for: ACK or NAK by seq, and the HELLO_REPLY (guarded by ``locks.replies``)."""

    def __init__(self, condition: threading.Condition):
        self.condition = condition
        self._awaiting: set[int] = set()
        self._answers: dict[int, int | None] = {}  # seq → None (ACK) or a NAK reason
        self.hello: bytes | None = None

    def expect(self, seq: int) -> None:
        with self.condition:
            self._awaiting.add(seq)

    def answer(self, seq: int, reason: int | None) -> None:
        with self.condition:
            if seq in self._awaiting:
                self._answers[seq] = reason
                self.condition.notify_all()

    def hello_arrived(self, payload: bytes) -> None:
        with self.condition:
            self.hello = payload
            self.condition.notify_all()

    def wait(self, seq: int, timeout_s: float, hello: bool = False) -> tuple[bool, int | None]:
        """Wait for the answer to ``seq`` (or, with ``hello``, a HELLO_REPLY); (answered, NAK reason or None).
        The seq is forgotten either way."""
        try:
            with self.condition:
                arrived = self.condition.wait_for(lambda: seq in self._answers or hello and self.hello is not None,
                                                  timeout_s)
                return arrived, self._answers.get(seq)
        finally:
            with self.condition:
                self._awaiting.discard(seq)
                self._answers.pop(seq, None)


class Session:
    """The connection to one plate driver and its state (:attr:`state`)."""

    def __init__(self, port: str, profile: PlateProfile, rate_hz: int, carrier_hz: float, transport: Transport,
                 locks: DriverLocks, account: RunAccount, counters: SerialCounters, ack_timeout_s: float,
                 amplitude_loop: bool, has_baseline: Callable[[], bool], bound: Callable[[Limits], None],
                 fresh: Callable[[], None], batch_s: float | None = None):
        self.port, self.profile, self.rate_hz, self.carrier_hz = port, profile, rate_hz, carrier_hz
        self.batch_s = batch_s  # s between SETPOINTS frames: checked against what the device says its link carries
        self.transport, self.ack_timeout_s, self.amplitude_loop = transport, ack_timeout_s, amplitude_loop
        self.state = SessionState()
        self.replies = Replies(locks.replies)
        self.limits = Limits.of(profile)
        self.notes: list[str] = []  # one line each: where the device's facts bind the host (limits, version)
        self.account, self.counters = account, counters
        self._has_baseline, self._bound, self._fresh = has_baseline, bound, fresh
        self._attempt, self._retry_at = 0, 0.0  # reconnections: the next try's backoff, and when it may come
        self._zeros = np.zeros(16)
        self.rest_failure: str | None = None

    def send(self, kind: int, payload: bytes = b"") -> int:
        """Write one command, not awaiting its answer; its seq."""
        return self.transport.send(kind, payload)

    def command(self, kind: int, payload: bytes, timeout_s: float | None = None) -> None:
        """Send a command and wait for its ACK; DeviceError on a NAK or no answer within ``ack_timeout_s``."""
        timeout_s = self.ack_timeout_s if timeout_s is None else timeout_s
        seq = self.transport.send(kind, payload, expect=self.replies.expect)
        answered, reason = self.replies.wait(seq, timeout_s)
        name = COMMAND_NAMES.get(kind, hex(kind))
        if not answered:
            raise DeviceError(f"{self.port}: no acknowledgement of {name} from the plate driver within {timeout_s:g} s")
        if reason is not None:
            raise DeviceError(f"{self.port}: the plate driver refused {name}: "
                              f"{p.NAK_REASONS.get(reason, f'reason {reason}')}")

    def handshake(self) -> p.HelloReply:
        """HELLO, and the device's answer: its HELLO_REPLY (checked), or a NAK or silence reported in one line."""
        with self.replies.condition:
            self.replies.hello = None
        seq = self.transport.send(p.HELLO, p.hello_payload(), expect=self.replies.expect)
        arrived, reason = self.replies.wait(seq, self.ack_timeout_s, hello=True)
        raw = self.replies.hello
        if not arrived:
            raise DeviceError(f"{self.port}: no answer to the handshake; is a plate driver there, "
                              f"speaking ultraglide protocol v{p.PROTOCOL_VERSION}?")
        if raw is None:
            raise DeviceError(f"{self.port}: the plate driver refused the handshake (HELLO: "
                              f"{p.NAK_REASONS.get(reason, f'reason {reason}')}); it does not speak ultraglide "
                              f"protocol v{p.PROTOCOL_VERSION} as docs/protocol.md describes")
        return check_device(self.port, raw, self.carrier_hz, self.rate_hz, self.batch_s)

    def bind(self, hello: p.HelloReply) -> None:
        """The device's limits bind from now on (the output stage's limiter is told)."""
        self.limits, notes = bind_limits(self.profile, self.limits, hello)
        if self.state.device is None and hello.restart_reason not in (None, p.RESTART_POWER_ON):
            # the run's first handshake: how the board came to be running
            notes.append(f"the plate driver last started after a restart: {hello.restart_words()}")
        self.state.device = hello
        self.state.handshakes += 1
        if self.state.why_restarted:  # the device restarted mid-run (its counters began again)
            self.state.why_restarted = False
            self.restarted_mid_run(hello)
        self._bound(self.limits)
        self.notes.extend(note for note in notes if note not in self.notes)

    def restarted_mid_run(self, hello: p.HelloReply) -> None:
        """The device restarted under the run, and ``hello`` is its handshake since: a device fault where it reset
        itself (a watchdog, a fault handler), said as the handshake says it."""
        if hello.restart_reason in (p.RESTART_WATCHDOG, p.RESTART_FAULT):
            self.account.board_restarted(hello.restart_words())

    def connect(self) -> None:
        """Open, handshake, bind, take the run's first telemetry, set the carrier, enable; DeviceError if not."""
        state = self.state
        self._fresh()  # only what this connection reports counts
        self.transport.open()
        state.active = False
        try:
            hello = self.handshake()
            self.bind(hello)
            first = not self._has_baseline()
            state.first_telemetry = threading.Event() if first else None
            state.active = True
            if first and not state.first_telemetry.wait(self.ack_timeout_s):  # the run's fault baseline
                impossible = self.account.field_check.words()
                raise DeviceError(f"{self.port}: the plate driver sends no telemetry" +
                                  ("" if impossible is None else f" that can be believed ({impossible})"))
            state.loop_on = False
            if self.amplitude_loop and hello.has_amplitude_loop:  # only while disabled: before ENABLE, and after
                self.command(p.ENABLE, p.enable_payload(False))  # a hang the device may still be enabled (NAK 3)
                self.command(p.SET_LOOP, p.set_loop_payload(1))
                state.loop_on = True
            self.command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
            if not state.cut:  # a device that cut itself out over this run is never re-enabled by the host
                self.command(p.ENABLE, p.enable_payload(True))
                state.output_on, state.enabled_at = True, time.perf_counter()
            state.last_heard = time.monotonic()
            state.connected.set()
        except (serial.SerialException, OSError) as error:
            self.disconnect()
            raise DeviceError(f"{self.port}: lost during the handshake ({error})") from None
        except BaseException:
            self.rest_now(REST_ACK_S)  # zero and disable while the link works: the device may have enabled
            self.disconnect()
            raise

    def reconnect(self) -> bool | None:
        """While the link is down (the writer thread): connect again once the backoff allows. True when back,
        False when the try failed (the next waits longer: 0.05 s doubling to 1.6 s), None when not yet tried."""
        if time.monotonic() < self._retry_at:
            return None
        self.disconnect()
        try:
            self.connect()
        except DeviceError as error:
            self._retry_at = time.monotonic() + BACKOFF_S[min(self._attempt, len(BACKOFF_S) - 1)]
            self._attempt += 1
            if len(self.counters.errors) < 20:
                self.counters.errors.append(str(error))
            self.account.retry_failed(str(error))
            return False
        self._attempt = 0
        return True

    def retry_soon(self) -> None:
        """The port just failed under the writer: the first reconnection waits the shortest backoff."""
        self._retry_at = time.monotonic() + BACKOFF_S[0]

    def disconnect(self) -> None:
        self.state.connected.clear()
        self.transport.close()

    def rest_now(self, ack_timeout_s: float | None = None) -> bool:
        """Zero setpoints (at the stream's next index) and ENABLE 0, acknowledged; False if the link failed."""
        if not self.transport.is_open:
            return False
        try:
            self.transport.send(p.SETPOINTS, setpoints=self._zeros)
            self.command(p.ENABLE, p.enable_payload(False), ack_timeout_s)
            self.state.output_on = False
            return True
        except (serial.SerialException, OSError, DeviceError) as error:
            self.rest_failure = str(error).splitlines()[0] if str(error) else type(error).__name__
            return False

    @property
    def watchdog_s(self) -> float:
        """The device's watchdog timeout (s): a stream must send something more often."""
        device = self.state.device
        return (device.watchdog_ms if device is not None else p.WATCHDOG_MS) / 1000.0

    @property
    def buffer_ms(self) -> float:
        """The device's jitter buffer (ms)."""
        device = self.state.device
        return float(device.buffer_ms if device is not None else p.BUFFER_MS)

    def force_reference(self, source) -> p.ForceReference | None:
        """What SETPOINTS_FORCE carries for the values just pulled: the force the source's friction loop computed
        them at and its model's exponent there, with the host's limit; None (plain SETPOINTS) while the loop does
        not follow, or for a device without the force correction."""
        device = self.state.device
        if device is None or not device.has_force_correction:
            return None
        reference = getattr(source, "force_reference", None)
        if reference is None:
            return None
        limit = math.floor(self.limits.limit_um_pp / self.limits.full_scale_um_pp * p.SETPOINT_SCALE)
        return p.ForceReference(reference[0], reference[1], limit / p.SETPOINT_SCALE)

    def set_carrier(self, carrier_hz: float) -> None:
        """Change the carrier now (Hz) and wait for the device's ACK; DeviceError if it refuses or is gone."""
        self.profile.check_carrier(carrier_hz)
        device = self.state.device
        if device is not None and not device.carrier_min_hz <= carrier_hz <= device.carrier_max_hz:
            raise DeviceError(f"{self.port}: carrier {carrier_hz:g} Hz is outside what the plate driver accepts, "
                              f"{device.carrier_min_hz:g}-{device.carrier_max_hz:g} Hz")
        self.carrier_hz = float(carrier_hz)
        try:
            self.command(p.SET_CARRIER, p.carrier_payload(self.carrier_hz))
        except (serial.SerialException, OSError) as error:
            raise DeviceError(f"{self.port}: lost while setting the carrier ({error})") from None
