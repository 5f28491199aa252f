"""``plate check``: a plate driver exercised against docs/protocol.md, one verdict per rule.

The check speaks the protocol itself, frame by frame (:class:`Probe`: the seq it chooses, the bytes it wants,
every answer timed), not through the streaming driver: each rule of the page's Conformance section that a
host can observe is exercised on purpose, and the verdict says what was seen. It drives the plate at 15 % of
the device's limit at most, at its resonance; the one rule that must ask for more than the limit (the
device's limiter, [R-LIMIT]) does it at the carrier farthest from resonance, where that code moves the plate
less than the 15 %, and only once a safe level there has shown it. Any telemetry above half the limit stops
the check at once (ENABLE 0). Over-limit and the trip need the plate itself above its limit: checked only
when asked (``over_limit=True``), at the limit, on a plate that can take 1 % over it for a moment.

Example::

    report = check_device("/dev/ttyACM0", profile)
    for verdict in report.verdicts:
        print(verdict.line())      # R-NAK-ORDER  pass  Host → device: NAK 1 for type 0x42, ...
    report.exit_status             # 0 when no rule failed

Verdicts: ``pass``, ``fail`` (the rule is broken, with what was seen), ``not checked`` (the device cannot
show it: a v2 session without v3's telemetry, no sensor, no amplitude loop; or a rule that needs the plate
above its limit).
"""

from __future__ import annotations

import contextlib
import math
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.serial_plate import open_port

PASS, FAIL, NOT_CHECKED = "pass", "fail", "not checked"
EXIT_NONCONFORMING = 6  # a rule failed (the exit statuses of a run, 3-5, are in run_report)
EXIT_LOST = 4  # as a run's: the device went away before the check could finish
SAFE_FRACTION = 0.15  # of the device's limit: the most the check asks at resonance
ABORT_FRACTION = 0.5  # a measured amplitude above this fraction of the limit stops the check at once
ANSWER_SLACK_S = 0.025  # the host's own share of an answer's time (scheduling, the link): on top of 50 ms
TIMEOUT_S = 1.0  # an answer that has not come by then is missing
SILENCE_S = 5.0  # no telemetry for this long: the device is gone (a plate on a loaded machine may pause for a second)
WRITE_TIMEOUT_S = 5.0  # a device that takes no byte for this long is gone (a busy one, on a loaded machine, is slow)
RETRIES = 1  # a failed rule is checked again this many times: it fails only if it fails every time
# rule → the section of docs/protocol.md that states it (its Conformance table; a test checks the two agree)
RULES = {
    "R-FRAMING": "Framing", "R-CRC": "Framing", "R-DEVICE-SEQ": "Framing", "R-SEQ-ECHO": "Framing",
    "R-VERSION": "Version negotiation", "R-HELLO-NO-STATE": "Version negotiation",
    "R-NAK-ORDER": "Host → device", "R-NAK-NO-EFFECT": "Host → device", "R-ACK": "Host → device",
    "R-CARRIER": "Host → device", "R-TELEMETRY": "Device → host", "R-SENSORS": "Device → host",
    "R-SCALING": "Setpoints", "R-RATE": "Setpoints", "R-EXPECTED": "Setpoints", "R-OVERRUN": "Setpoints",
    "R-PREFILL": "Setpoints", "R-UNDERRUN": "Setpoints", "R-DISCARD": "Setpoints", "R-ENABLE": "Enable",
    "R-LIMIT": "Limits", "R-OVER-LIMIT": "Limits", "R-TRIP": "Limits", "R-WATCHDOG": "Watchdog",
    "R-FAULT-LATCH": "Faults", "R-FAULT-COUNT": "Faults", "R-CLEAR-FAULTS": "Faults",
    "R-LOOP": "The amplitude loop",
}
BAD_COMMAND = p.FAULT_BAD_COMMAND.bit_length() - 1
UNDERRUN = p.FAULT_UNDERRUN.bit_length() - 1
WATCHDOG = p.FAULT_WATCHDOG.bit_length() - 1
OVERRUN = p.FAULT_OVERRUN.bit_length() - 1
OVER_LIMIT = p.FAULT_OVER_LIMIT.bit_length() - 1
TRIP = p.FAULT_TRIP.bit_length() - 1


class Abort(DeviceError):
    """The check stopped: the plate moved more than it was asked, or the device went away (``lost``)."""

    def __init__(self, message: str, lost: bool = True):
        super().__init__(message)
        self.lost = lost


class Broken(DeviceError):
    """A rule's check saw the device break it (the message says what it saw); a verdict, never raised out."""


class Unobservable(DeviceError):
    """The device cannot show this rule (the message says why)."""


@dataclass(frozen=True)
class Verdict:
    """One rule's outcome: ``pass``, ``fail`` or ``not checked``, with what was seen, in words."""

    rule: str
    outcome: str
    seen: str

    @property
    def section(self) -> str:
        return RULES[self.rule]

    def line(self) -> str:
        return f"{self.rule:<17} {self.outcome:<11} {self.section}: {self.seen}"

    def as_dict(self) -> dict:
        return {"rule": self.rule, "section": self.section, "verdict": self.outcome, "seen": self.seen}


@dataclass(frozen=True)
class CheckReport:
    """The device as it described itself, and every rule's verdict in the order checked."""

    device: p.HelloReply
    verdicts: tuple[Verdict, ...]
    aborted: str | None = None
    seconds: float = 0.0
    lost: bool = False  # the check stopped because the device went away (not because it moved too much)

    def count(self, outcome: str) -> int:
        return sum(verdict.outcome == outcome for verdict in self.verdicts)

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(verdict.rule for verdict in self.verdicts if verdict.outcome == FAIL)

    @property
    def exit_status(self) -> int:
        """0: no rule failed; 6: a rule failed, or the plate moved more than asked; 4: the device was lost first."""
        if self.aborted and self.lost and not self.failed:
            return EXIT_LOST
        return EXIT_NONCONFORMING if self.failed or self.aborted else 0

    @property
    def verdict(self) -> str:
        """The outcome in words, with the exit status."""
        if self.failed:
            words = f"the plate driver broke {len(self.failed)} rule{'s' if len(self.failed) > 1 else ''} " \
                    f"({', '.join(self.failed)})"
        elif self.aborted:
            words = f"the check could not finish ({self.aborted})"
        else:
            words = "no rule broken"
        return f"{words} (exit status {self.exit_status})"

    def summary(self) -> str:
        words = (f"{self.count(PASS)} rules pass, {self.count(FAIL)} fail, {self.count(NOT_CHECKED)} not checked "
                 f"({self.seconds:.1f} s)")
        return words + (f"; stopped: {self.aborted}" if self.aborted else "")

    def as_dict(self) -> dict:
        d = self.device
        return {"device": {"name": d.name, "version": d.version, "full_scale_um_pp": d.full_scale_um_pp,
                           "max_amplitude_um_pp": d.max_amplitude_um_pp,
                           "max_drive_um_pp": getattr(d, "max_drive_um_pp", d.max_amplitude_um_pp),
                           "resonance_hz": d.resonance_hz, "carrier_min_hz": d.carrier_min_hz,
                           "carrier_max_hz": d.carrier_max_hz, "watchdog_ms": d.watchdog_ms, "buffer_ms": d.buffer_ms},
                "rules": [verdict.as_dict() for verdict in self.verdicts], "passed": self.count(PASS),
                "failed": self.count(FAIL), "not_checked": self.count(NOT_CHECKED), "broken_rules": list(self.failed),
                "aborted": self.aborted, "lost": self.lost,
                "seconds": round(self.seconds, 2)}


# ---- the link, frame by frame -------------------------------------------------------------------------------
class Probe:
    """The protocol spoken by hand on a port: frames sent with the seq chosen, frames received timed
    (perf_counter s), in order. A telemetry frame above ``abort_um_pp`` disables the output at once."""

    def __init__(self, port: str, baudrate: int = 921600):
        self.port = port
        self.serial = open_port(port, baudrate, write_timeout_s=WRITE_TIMEOUT_S)
        self.decoder = p.FrameDecoder()
        self.frames: list[tuple[float, p.Frame]] = []
        self.first_seq: int | None = None
        self.unsafe: str | None = None
        self.abort_um_pp = math.inf
        self.lost: str | None = None
        self._arrived = threading.Condition()
        self._write_lock = threading.Lock()
        self._seq = 0x100
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read, name="plate-check-reader", daemon=True)
        self._reader.start()

    def close(self) -> None:
        self._stop.set()
        self._reader.join(timeout=2)
        self.serial.close()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.serial.read(1)  # at once when a byte comes (timeout 50 ms), then what else is there
                if data and self.serial.in_waiting:
                    data += self.serial.read(self.serial.in_waiting)
            except Exception as error:  # noqa: BLE001 - the port went away: said by the next wait
                self.lost = f"the port failed ({error})"
                return
            if not data:
                continue
            now = time.perf_counter()
            frames = self.decoder.feed(data)
            for frame in frames:
                if self.first_seq is None:
                    self.first_seq = frame.seq
                if frame.kind == p.TELEMETRY and self.unsafe is None:
                    self._watch(frame)
            with self._arrived:
                self.frames.extend((now, frame) for frame in frames)
                self._arrived.notify_all()

    def _watch(self, frame: p.Frame) -> None:
        try:
            measured = p.parse_telemetry(frame.payload).measured_um_pp
        except p.ProtocolError:
            return
        if measured > self.abort_um_pp:
            self.unsafe = f"the plate measured {measured:.3g} µm p-p, more than it was asked"
            self.send(p.ENABLE, p.enable_payload(False))  # at once, from here: the check's thread may be waiting

    # ---- out ----
    def next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFFFF
        return self._seq

    def send(self, kind: int, payload: bytes = b"", seq: int | None = None) -> tuple[int, float]:
        """One frame; returns its seq and when its last byte was handed to the port (perf_counter s)."""
        seq = self.next_seq() if seq is None else seq
        self.send_bytes(p.encode_frame(kind, seq, payload))
        return seq, time.perf_counter()

    def send_bytes(self, data: bytes) -> None:
        with self._write_lock:
            try:
                self.serial.write(data)
                self.serial.flush()
            except Exception as error:  # noqa: BLE001 - the device is gone: the check stops
                raise Abort(f"{self.port}: the port failed ({error})") from None

    # ---- in ----
    def mark(self) -> int:
        """Where the frames received so far end: ``wait(..., since=mark)`` looks only after it."""
        with self._arrived:
            return len(self.frames)

    def check(self) -> None:
        if self.unsafe:
            raise Abort(self.unsafe, lost=False)
        if self.lost:
            raise Abort(self.lost)

    def wait(self, wanted: Callable[[p.Frame], bool], since: int, timeout_s: float = TIMEOUT_S):
        """The first frame after ``since`` that ``wanted`` accepts, as (time, frame, its index); None by the
        deadline."""
        deadline = time.perf_counter() + timeout_s
        with self._arrived:
            index = since
            while True:
                while index < len(self.frames):
                    t, frame = self.frames[index]
                    index += 1
                    if wanted(frame):
                        return t, frame, index - 1
                left = deadline - time.perf_counter()
                if left <= 0:
                    return None
                self._arrived.wait(min(left, 0.05))

    def received(self, since: int, kind: int | None = None) -> list[tuple[float, p.Frame]]:
        with self._arrived:
            return [(t, f) for t, f in self.frames[since:] if kind is None or f.kind == kind]

    def answer(self, seq: int, since: int, timeout_s: float = TIMEOUT_S):
        """The answer to the command sent with ``seq`` after ``since``: the ACK or NAK naming it, else the first
        ACK or NAK that came (the check sends one command at a time; [R-SEQ-ECHO] judges the seq it named):
        ("ack" | "nak", reason or None, arrival time, the seq it named); None if none came."""
        def answers(frame: p.Frame) -> bool:
            return frame.kind in (p.ACK, p.NAK) and len(frame.payload) >= 2

        def naming(frame: p.Frame) -> bool:
            return answers(frame) and struct.unpack_from("<H", frame.payload)[0] == seq

        found = self.wait(answers, since, timeout_s)
        if found is None:
            return None
        if not naming(found[1]):  # an earlier command's late answer, or a device that names no seq: a moment more
            found = self.wait(naming, found[2] + 1, 0.1) or found
        t, frame, _ = found
        named = struct.unpack_from("<H", frame.payload)[0]
        return ("ack", None, t, named) if frame.kind == p.ACK else ("nak", frame.payload[2], t, named)

    def command(self, kind: int, payload: bytes = b"", timeout_s: float = TIMEOUT_S, seq: int | None = None):
        """Send and wait for its answer: ("ack" | "nak", reason, seconds it took, the seq it named), or None."""
        self.check()
        since = self.mark()
        seq, sent = self.send(kind, payload, seq)
        found = self.answer(seq, since, timeout_s)
        return None if found is None else (found[0], found[1], found[2] - sent, found[3])

    def telemetry(self, since: int | None = None, timeout_s: float = SILENCE_S) -> p.Telemetry:
        """The next TELEMETRY frame after ``since`` (default: from now)."""
        self.check()
        found = self.wait(lambda f: f.kind == p.TELEMETRY, self.mark() if since is None else since, timeout_s)
        if found is None:
            raise Abort(f"{self.port}: no telemetry for {timeout_s:g} s")
        return p.parse_telemetry(found[1].payload)

    def hello(self, version: int, timeout_s: float = TIMEOUT_S):
        """(HelloReply or None if malformed, its raw payload, seconds it took), or None without an answer."""
        since = self.mark()
        _, sent = self.send(p.HELLO, p.hello_payload(version))
        found = self.wait(lambda f: f.kind == p.HELLO_REPLY, since, timeout_s)
        if found is None:
            return None
        t, frame, _ = found
        try:
            reply = p.parse_hello_reply(frame.payload)
        except p.ProtocolError:
            reply = None
        return reply, frame.payload, t - sent


# ---- the check -------------------------------------------------------------------------------------------
class Check:
    """One run of the rules against a device (see the module docstring)."""

    def __init__(self, probe: Probe, profile: PlateProfile, over_limit: bool = False, say=None, heading=None,
                 hold=None, only: tuple[str, ...] = ()):
        unknown = [rule for rule in only if rule not in RULES]
        if unknown:
            raise DeviceError(f"no rule {', '.join(unknown)}; the rules are {', '.join(RULES)}")
        self.only = only
        self.probe = probe
        self.profile = profile
        self.over_limit = over_limit
        self.say = say or (lambda verdict: None)
        self.heading = heading or (lambda line: None)
        self.hold = hold or contextlib.nullcontext
        self.device: p.HelloReply | None = None
        self.version = 3
        self.rate = 1000
        self.index = 0
        self.verdicts: list[Verdict] = []

    # ---- facts of the device ----
    @property
    def limit_code(self) -> int:
        """The largest code whose drive is not above the device's limit."""
        d = self.device
        return min(p.SETPOINT_SCALE, math.floor(d.max_amplitude_um_pp / d.full_scale_um_pp * p.SETPOINT_SCALE))

    @property
    def safe_limit_um_pp(self) -> float:
        """The smaller of the device's and the profile's limit: what the check's safe level is a fraction of."""
        return min(self.device.max_amplitude_um_pp, self.profile.max_amplitude_um_pp)

    @property
    def safe_code(self) -> int:
        """The code of 15 % of the safe limit, in the device's full scale."""
        d = self.device
        return max(1, math.floor(SAFE_FRACTION * self.safe_limit_um_pp / d.full_scale_um_pp * p.SETPOINT_SCALE))

    @property
    def prefill(self) -> int:
        return math.ceil(p.PREFILL_MS * self.rate / 1000)

    @property
    def capacity(self) -> int:
        return math.floor(self.device.buffer_ms * self.rate / 1000)

    @property
    def frame_values(self) -> int:
        return max(1, self.rate // 100)  # a frame every 10 ms

    @property
    def v3(self) -> bool:
        return self.version >= 3

    def need_v3(self) -> None:
        if not self.v3:
            raise Unobservable("needs v3's telemetry (playback, buffer, drive), and this session is v2")

    # ---- what the device says ----
    def telemetry(self, timeout_s: float = SILENCE_S, feed: bool = True) -> p.Telemetry:
        """The next TELEMETRY frame; while waiting, HEARTBEAT every 25 ms keeps the watchdog fed (``feed``)."""
        since = self.probe.mark()
        deadline = time.perf_counter() + timeout_s
        while True:
            left = deadline - time.perf_counter()
            found = self.probe.wait(lambda f: f.kind == p.TELEMETRY, since, min(0.025, max(0.0, left)))
            if found is not None:
                return p.parse_telemetry(found[1].payload)
            self.probe.check()
            if left <= 0:
                raise Abort(f"{self.probe.port}: no telemetry for {timeout_s:g} s")
            if feed:
                self.probe.send(p.HEARTBEAT)

    def counts(self) -> tuple[int, ...]:
        return self.telemetry().fault_counts

    # ---- doing things ----
    def command(self, kind: int, payload: bytes = b"", seq: int | None = None):
        return self.probe.command(kind, payload, seq=seq)

    def must(self, kind: int, payload: bytes, what: str) -> None:
        """A command that must be acknowledged for the check to go on."""
        answer = self.command(kind, payload)
        if answer is None or answer[0] != "ack":
            got = "no answer" if answer is None else f"NAK {answer[1]}"
            raise Broken(f"{what} was not acknowledged ({got})")

    def enable(self, on: bool) -> None:
        """ENABLE, and telemetry showing it took (its ACK is [R-ACK]'s to judge, not waited for here: the wait
        would starve the watchdog of a device that never answers)."""
        self.probe.send(p.ENABLE, p.enable_payload(on))
        telemetry = self.settled_telemetry(lambda t: t.enabled == on)
        if telemetry.enabled != on:
            raise Broken(f"ENABLE {int(on)} did not take: telemetry says the output is "
                         f"{'on' if telemetry.enabled else 'off'}")

    def setpoints(self, code: int, count: int, first: int | None = None, rate: int | None = None) -> int:
        """One SETPOINTS frame of ``count`` values of ``code`` (from the stream's next index, unless ``first``);
        returns its seq. The stream's index moves past it."""
        first = self.index if first is None else first
        payload = struct.pack("<IIH", first & 0xFFFFFFFF, rate or self.rate, count) + \
            np.full(count, code, dtype="<u2").tobytes()
        seq, _ = self.probe.send(p.SETPOINTS, payload)
        self.index = (first + count) & 0xFFFFFFFF
        return seq

    def stream(self, seconds: float, code: int, rate: int | None = None) -> float:
        """Frames of ``code`` every 10 ms for ``seconds``, on time; the first carries 60 ms more (a cushion
        against this host's own scheduling on a loaded machine: the device's buffer holds some 70 ms; less in a
        buffer under 80 ms). Returns when the last went."""
        cushion = min(6, max(0, (self.device.buffer_ms - 20) // 10))  # frames' worth: less in a buffer under 80 ms
        start = time.perf_counter()
        frames = max(1, round(seconds / 0.01))
        per_frame = self.frame_values if rate is None else max(1, rate // 100)
        sent = start
        for k in range(frames):
            self.probe.check()
            due = start + 0.01 * k
            time.sleep(max(0.0, due - time.perf_counter()))
            self.setpoints(code, per_frame * (1 + cushion if k == 0 else 1), rate=rate)
            sent = time.perf_counter()
        return sent

    def quiet(self, seconds: float, heartbeat: bool = True) -> None:
        """Wait, feeding the watchdog with HEARTBEAT every 25 ms (or not)."""
        end = time.perf_counter() + seconds
        while (left := end - time.perf_counter()) > 0:
            self.probe.check()
            if heartbeat:
                self.probe.send(p.HEARTBEAT)
            time.sleep(min(0.025, left))

    def reset(self) -> None:
        """Between rules: output off, faults cleared, the carrier at resonance, a telemetry frame of it."""
        self.probe.check()
        self.enable(False)
        self.must(p.CLEAR_FAULTS, p.clear_faults_payload(0xFFFF), "CLEAR_FAULTS")
        self.must(p.SET_CARRIER, p.carrier_payload(self.carrier), "SET_CARRIER")
        self.telemetry()

    @property
    def carrier(self) -> float:
        d = self.device
        return min(max(d.resonance_hz, d.carrier_min_hz), d.carrier_max_hz)

    def settled_telemetry(self, wanted: Callable[[p.Telemetry], bool], frames: int = 10) -> p.Telemetry:
        """The first telemetry frame that ``wanted`` accepts among the next ``frames`` (else the last)."""
        telemetry = self.telemetry()
        for _ in range(frames - 1):
            if wanted(telemetry):
                return telemetry
            telemetry = self.telemetry()
        return telemetry

    # ---- the run ----
    def run(self) -> CheckReport:
        started = time.perf_counter()
        aborted, lost = None, False
        try:
            self.setup()
            self.heading(self.describe())
            for rule, check in self.rules():
                if not self.only or rule in self.only:
                    self.run_rule(rule, check)
        except Abort as error:
            if self.device is None:  # gone before it described itself: nothing to report but that
                raise DeviceError(str(error)) from None
            aborted, lost = str(error), error.lost
        finally:
            with self.hold():  # a stop signal waits until the plate is at rest
                self.rest()
        return CheckReport(self.device, tuple(self.verdicts), aborted, time.perf_counter() - started, lost)

    def describe(self) -> str:
        """One line: the device as it described itself, and the most the check asks of it."""
        d = self.device
        safe_um_pp = self.safe_code / p.SETPOINT_SCALE * d.full_scale_um_pp
        bound = "the plate driver's" if d.max_amplitude_um_pp <= self.profile.max_amplitude_um_pp else \
            f"the profile {self.profile.name}'s"
        return (f"checking {d.name!r} on {self.probe.port}: protocol v{self.version}, limit "
                f"{d.max_amplitude_um_pp:g} µm p-p of full scale {d.full_scale_um_pp:g}, resonance "
                f"{d.resonance_hz:g} Hz; driving at most {safe_um_pp:.2f} µm p-p ({100 * SAFE_FRACTION:.0f} % of "
                f"{bound} {self.safe_limit_um_pp:g} µm p-p limit) at {self.carrier:g} Hz")

    def run_rule(self, rule: str, check) -> None:
        """One rule's verdict. A rule that fails is checked once more: this host's own stalls on a loaded machine
        (late frames, frames dropped by a full link) can make a device look wrong once; a broken rule fails both
        times. A pass after a failure says what the first try saw."""
        first = None
        for _ in range(1 + RETRIES):
            try:
                self.reset()
                outcome, seen = PASS, check()
            except Broken as error:
                outcome, seen = FAIL, str(error)
            except Unobservable as error:
                outcome, seen = NOT_CHECKED, str(error)
            if outcome != FAIL or first is not None:
                break
            first = seen
        if first is not None:
            seen = f"{seen} (the first try failed: {first})" if outcome != FAIL else f"{first} (again on a second try)"
        verdict = Verdict(rule, outcome, seen)
        self.verdicts.append(verdict)
        self.say(verdict)

    def setup(self) -> None:
        answer = self.probe.hello(p.PROTOCOL_VERSION, timeout_s=p.HOST_ACK_TIMEOUT_S)
        if answer is None:
            raise DeviceError(f"{self.probe.port}: no answer to HELLO; is a plate driver there?")
        reply, raw, _ = answer
        if reply is None or reply.version not in p.SUPPORTED_VERSIONS:
            raise DeviceError(f"{self.probe.port}: the plate driver answered HELLO in protocol "
                              f"v{raw[0] if raw else '?'}; plate check speaks v2 and v3")
        self.device, self.version = reply, reply.version
        self.rate = min(max(1000, reply.min_setpoint_rate_hz), reply.max_setpoint_rate_hz)
        self.probe.abort_um_pp = ABORT_FRACTION * self.safe_limit_um_pp
        self.telemetry()

    def rest(self) -> None:
        """Zero and disable on every way out, while the link works (whatever stopped the check)."""
        with contextlib.suppress(Exception):  # best effort on the way out: a lost port takes nothing
            since = self.probe.mark()
            self.setpoints(0, max(1, self.frame_values))
            seq, _ = self.probe.send(p.ENABLE, p.enable_payload(False))
            self.probe.answer(seq, since, p.ACK_DEADLINE_MS / 1000 + ANSWER_SLACK_S)

    def rules(self):
        return [
            ("R-TELEMETRY", self.check_telemetry), ("R-DEVICE-SEQ", self.check_device_seq),
            ("R-SEQ-ECHO", self.check_seq_echo), ("R-ACK", self.check_ack), ("R-VERSION", self.check_version),
            ("R-CRC", self.check_crc), ("R-FRAMING", self.check_framing), ("R-NAK-ORDER", self.check_nak_order),
            ("R-NAK-NO-EFFECT", self.check_nak_no_effect), ("R-CARRIER", self.check_carrier),
            ("R-ENABLE", self.check_enable), ("R-DISCARD", self.check_discard),
            ("R-PREFILL", self.check_prefill), ("R-EXPECTED", self.check_expected),
            ("R-OVERRUN", self.check_overrun), ("R-UNDERRUN", self.check_underrun),
            ("R-WATCHDOG", self.check_watchdog), ("R-FAULT-COUNT", self.check_fault_count),
            ("R-FAULT-LATCH", self.check_fault_latch), ("R-CLEAR-FAULTS", self.check_clear_faults),
            ("R-HELLO-NO-STATE", self.check_hello_no_state), ("R-SCALING", self.check_scaling),
            ("R-LIMIT", self.check_limit), ("R-OVER-LIMIT", self.check_over_limit), ("R-TRIP", self.check_trip),
            ("R-SENSORS", self.check_sensors), ("R-LOOP", self.check_loop),
            ("R-RATE", self.check_rate),  # last: a device that keeps a stream's rate would refuse every rule after
        ]

    # ---- the rules ----
    def check_telemetry(self) -> str:
        since = self.probe.mark()
        time.sleep(2.05)
        times = np.array([t for t, _ in self.probe.received(since, p.TELEMETRY)])
        layout = 89 if self.v3 else 71
        sizes = {len(f.payload) for _, f in self.probe.received(since, p.TELEMETRY)}
        if sizes - {layout}:
            raise Broken(f"TELEMETRY of {sorted(sizes)} bytes in a v{self.version} session (its layout: {layout})")
        if len(times) < 2:
            raise Broken(f"{len(times)} TELEMETRY frames in 2 s")
        # the rate from first to last arrival: a frame's delivery delay (this host's scheduling, the link) moves
        # only the two ends, so over 2 s it moves the rate by a few percent, where counting frames in each second
        # would judge the host's jitter
        rate = (len(times) - 1) / (times[-1] - times[0])
        gap = float(np.diff(times).max())
        seen = f"{len(times)} frames in 2 s: {rate:.1f} a second (50 ± 10 %), at most {1000 * gap:.0f} ms apart"
        if abs(rate - p.TELEMETRY_HZ) > p.TELEMETRY_TOLERANCE * p.TELEMETRY_HZ:
            raise Broken(seen)
        return seen

    def check_device_seq(self) -> str:
        since = self.probe.mark()
        for _ in range(10):  # answers between telemetry frames: every frame counts, of every type
            self.command(p.CLEAR_FAULTS, p.clear_faults_payload(0))
            time.sleep(0.05)
        frames = [f for _, f in self.probe.received(since)]
        steps = [(b.seq - a.seq) & 0xFFFF for a, b in zip(frames, frames[1:], strict=False)]
        wrong = [k for k, step in enumerate(steps) if step != 1]
        kinds = sorted({f.kind for f in frames})
        if wrong:
            k = wrong[0]
            raise Broken(f"seq went from {frames[k].seq} ({frames[k].kind:#04x}) to {frames[k + 1].seq} "
                         f"({frames[k + 1].kind:#04x}) over {len(frames)} frames")
        first = self.probe.first_seq
        power_up = " (its first frame had seq 0)" if first == 0 else \
            f" (its first frame here had seq {first}: sent before the check was listening, not checked)"
        return (f"seq up by one from each of {len(frames)} frames to the next, types "
                f"{', '.join(f'{k:#04x}' for k in kinds)}{power_up}")

    def check_seq_echo(self) -> str:
        ack = self.command(p.CLEAR_FAULTS, p.clear_faults_payload(0), seq=0xBEEF)
        nak = self.command(0x42, b"", seq=0x1234)
        if ack is None or ack[0] != "ack" or ack[3] != 0xBEEF:
            named = f", naming {ack[3]:#06x}" if ack else ""
            raise Broken(f"CLEAR_FAULTS sent with seq 0xbeef: {_words(ack)}{named}")
        if nak is None or nak[0] != "nak" or nak[3] != 0x1234:
            named = f", naming {nak[3]:#06x}" if nak else ""
            raise Broken(f"type 0x42 sent with seq 0x1234: {_words(nak)}{named}")
        return "ACK named 0xbeef and NAK named 0x1234, the seqs of the frames they answered"

    def check_ack(self) -> str:
        """Each command answered within 50 ms; a slow answer is asked again (up to 3 times, the fastest counts):
        this host's own scheduling on a loaded machine can delay what it sees, never make it early."""
        deadline = p.ACK_DEADLINE_MS / 1000 + ANSWER_SLACK_S
        commands = [("SET_CARRIER", p.SET_CARRIER, p.carrier_payload(self.carrier)),
                    ("ENABLE 0", p.ENABLE, p.enable_payload(False)), ("ENABLE 1", p.ENABLE, p.enable_payload(True)),
                    ("ENABLE 0", p.ENABLE, p.enable_payload(False)),
                    ("CLEAR_FAULTS", p.CLEAR_FAULTS, p.clear_faults_payload(0)),
                    ("SET_LOOP 0", p.SET_LOOP, p.set_loop_payload(0)),
                    ("SIM_FAULT of no kind", p.SIM_FAULT, p.sim_fault_payload(0, 0)), ("HELLO", p.HELLO, b"")]
        slowest, worst = 0.0, ""
        for name, kind, payload in commands:
            fastest = math.inf
            for _ in range(3):
                if kind == p.HELLO:
                    hello = self.probe.hello(self.version)
                    took = None if hello is None else hello[2]
                else:
                    answer = self.command(kind, payload)
                    took = None if answer is None else answer[2]
                if took is None:
                    raise Broken(f"no answer to {name} within {TIMEOUT_S:g} s")
                fastest = min(fastest, took)
                if fastest <= deadline:
                    break
            if fastest > slowest:
                slowest, worst = fastest, name
        seen = f"{len(commands)} commands answered, the slowest in {1000 * slowest:.1f} ms ({worst})"
        if slowest > deadline:
            raise Broken(seen + f" at best of 3, over {p.ACK_DEADLINE_MS} ms")
        return seen

    def check_version(self) -> str:
        answers = {}
        for asked in (1, 2, 200, 3):
            hello = self.probe.hello(asked)
            if hello is None or hello[0] is None:
                raise Broken(f"HELLO {asked}: {'no answer' if hello is None else 'a malformed reply'}")
            answers[asked] = hello[0].version
        if answers[3] != self.device.version:
            self.probe.hello(self.device.version)
        lowest, highest = answers[1], answers[200]
        words = ", ".join(f"HELLO {asked} → v{version}" for asked, version in answers.items())
        expected = {1: lowest, 2: 2 if lowest <= 2 <= highest else lowest, 3: min(3, highest), 200: highest}
        wrong = [asked for asked, version in answers.items() if version != expected[asked]]
        if wrong or lowest > highest:
            raise Broken(f"{words}: a device whose versions run v{lowest}-v{highest} answers HELLO {wrong[0]} in "
                         f"v{expected[wrong[0]]}")
        self.version = answers[3]
        return words

    def check_crc(self) -> str:
        before = self.telemetry()
        frame = bytearray(p.encode_frame(p.CLEAR_FAULTS, 0x7777, p.clear_faults_payload(0)))
        body = bytearray(_cobs_decode(frame[:-1]))
        body[-1] ^= 0x5A  # the CRC's last byte
        since = self.probe.mark()
        self.probe.send_bytes(_cobs_encode(bytes(body)))
        if self.probe.answer(0x7777, since, 0.2) is not None:
            raise Broken("a frame with a bad CRC was answered")
        after = self.settled_telemetry(lambda t: t.crc_errors != before.crc_errors)
        if (after.crc_errors - before.crc_errors) & 0xFFFFFFFF != 1:
            raise Broken(f"crc_errors went up by {(after.crc_errors - before.crc_errors) & 0xFFFFFFFF}, not 1")
        # and bad frames feed no watchdog: a stream, then only frames with bad CRCs
        self.enable(True)
        self.stream(0.1, self.safe_code)
        watchdogs = self.counts()[WATCHDOG]
        bad = bytearray(_cobs_decode(p.encode_frame(p.HEARTBEAT, 1)[:-1]))
        bad[-1] ^= 0x5A
        for _ in range(int(4.5 * self.device.watchdog_ms / 20)):
            self.probe.send_bytes(_cobs_encode(bytes(bad)))
            time.sleep(0.02)
        fired = (self.counts()[WATCHDOG] - watchdogs) & 0xFFFFFFFF
        if fired != 1:
            raise Broken(f"frames with bad CRCs every 20 ms for {4.5 * self.device.watchdog_ms:g} ms: the watchdog "
                         f"fired {fired} times, not once (they must not feed it)")
        return "a frame with a bad CRC went unanswered and counted once; a stream of them fed no watchdog"

    def check_framing(self) -> str:
        before = self.telemetry()
        payload = bytes(range(1, 256)) * 4
        payload = payload[:p.MAX_BODY - 7]  # a frame of exactly MAX_BODY decoded bytes
        answer = self.command(0x42, payload)
        if answer is None or answer[:2] != ("nak", p.NAK_UNKNOWN_TYPE):
            raise Broken(f"a frame of {p.MAX_BODY} decoded bytes (type 0x42) was not taken: {_words(answer)}, "
                         "not NAK 1")
        self.probe.send_bytes(b"\x55" * (p.MAX_ENCODED + 70) + b"\x00")  # an over-long run, then a delimiter
        if self.command(p.CLEAR_FAULTS, p.clear_faults_payload(0)) is None:
            raise Broken("after an over-long run the next frame went unanswered")
        after = self.settled_telemetry(lambda t: t.framing_errors != before.framing_errors)
        errors = (after.framing_errors - before.framing_errors) & 0xFFFFFFFF
        if errors != 1:
            raise Broken(f"an over-long run of {p.MAX_ENCODED + 70} bytes made {errors} framing errors, not 1")
        return (f"a frame of {p.MAX_BODY} decoded bytes was taken (NAK 1); a run of {p.MAX_ENCODED + 70} bytes "
                "made one framing error, and the next frame was answered")

    def check_nak_order(self) -> str:
        cases = [
            ("type 0x42", 0x42, b"", p.NAK_UNKNOWN_TYPE),
            ("TELEMETRY (a device's type) sent to it", p.TELEMETRY, b"\x00" * 71, p.NAK_UNKNOWN_TYPE),
            ("ENABLE of 2 bytes, both out of range", p.ENABLE, b"\x07\x07", p.NAK_BAD_LENGTH),
            ("SET_CARRIER of 3 bytes", p.SET_CARRIER, b"\x00\x00\x00", p.NAK_BAD_LENGTH),
            ("SETPOINTS saying 300 values, carrying 1", p.SETPOINTS, struct.pack("<IIH", 0, self.rate, 300) + b"\0\0",
             p.NAK_BAD_LENGTH),
            ("ENABLE 7", p.ENABLE, b"\x07", p.NAK_BAD_VALUE),
            ("SETPOINTS of no value", p.SETPOINTS, struct.pack("<IIH", 0, self.rate, 0), p.NAK_BAD_VALUE),
        ]
        seen = []
        for name, kind, payload, reason in cases:
            answer = self.command(kind, payload)
            if answer is None or answer[:2] != ("nak", reason):
                raise Broken(f"{name}: {_words(answer)}, not NAK {reason}")
            seen.append(f"NAK {reason} for {name}")
        # NAK 4: SET_LOOP of the wrong length where the loop is not supported (a v2 session, or no loop)
        hello = self.probe.hello(2)
        session = hello[0].version if hello and hello[0] else self.version
        unsupported = session < 3 or not self.device.features & p.FEATURE_AMPLITUDE_LOOP
        answer = self.command(p.SET_LOOP, b"\x00\x00")
        self.probe.hello(self.version)
        wanted = p.NAK_UNSUPPORTED if unsupported else p.NAK_BAD_LENGTH
        if answer is None or answer[:2] != ("nak", wanted):
            raise Broken(f"SET_LOOP of 2 bytes in a v{session} session: {_words(answer)}, not NAK {wanted}")
        seen.append(f"NAK {wanted} for SET_LOOP of 2 bytes in a v{session} session")
        return "; ".join(seen) + " (NAK 5 needs a failing handler: not provoked)"

    def check_nak_no_effect(self) -> str:
        before = self.telemetry()
        wrong = self.device.carrier_max_hz + 500.0
        answer = self.command(p.SET_CARRIER, p.carrier_payload(wrong))
        if answer is None or answer[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_CARRIER {wrong:g} Hz, above the range: {_words(answer)}, not NAK 3")
        after = self.telemetry()
        raised = (after.fault_counts[BAD_COMMAND] - before.fault_counts[BAD_COMMAND]) & 0xFFFFFFFF
        if abs(after.carrier_hz - before.carrier_hz) > 0.01:
            raise Broken(f"a refused SET_CARRIER {wrong:g} Hz moved the carrier from {before.carrier_hz:g} to "
                         f"{after.carrier_hz:g} Hz")
        if raised != 1:
            raise Broken(f"a refused frame raised bad-command {raised} times, not once")
        return f"SET_CARRIER {wrong:g} Hz refused (NAK 3), the carrier stayed at {after.carrier_hz:g} Hz, " \
               "bad-command raised once"

    def check_carrier(self) -> str:
        d = self.device
        other = min(d.carrier_max_hz, self.carrier + 100.0) if self.carrier + 100.0 <= d.carrier_max_hz else \
            max(d.carrier_min_hz, self.carrier - 100.0)
        self.enable(True)
        self.stream(0.1, self.safe_code)
        answer = self.command(p.SET_CARRIER, p.carrier_payload(other))
        if answer is None or answer[0] != "ack":
            raise Broken(f"SET_CARRIER {other:g} Hz while enabled: {_words(answer)}, not ACK")
        telemetry = self.settled_telemetry(lambda t: abs(t.carrier_hz - other) < 0.01)
        if abs(telemetry.carrier_hz - other) > 0.01:
            raise Broken(f"SET_CARRIER {other:g} Hz acknowledged while enabled; telemetry says "
                         f"{telemetry.carrier_hz:g}")
        return f"SET_CARRIER {other:g} Hz while enabled: ACK, and telemetry says so (phase continuity is not " \
               "observable over the link)"

    def check_enable(self) -> str:
        self.need_v3()
        self.enable(False)  # while disabled: ACK, nothing else
        self.enable(True)
        self.stream(0.1, self.safe_code)
        self.probe.send(p.ENABLE, p.enable_payload(True))  # while playing: the stream goes on
        after = self.settled_telemetry(lambda t: t.expected_index == self.index, 3)
        if after.playback not in (p.PLAYBACK_PLAYING, p.PLAYBACK_DRY) or after.expected_index != self.index:
            raise Broken(f"ENABLE 1 while playing: then {p.PLAYBACK_NAMES.get(after.playback)}, expected index "
                         f"{after.expected_index} (the stream's next is {self.index}): a new stream")
        lost = after.lost_setpoints
        self.setpoints(self.safe_code, self.frame_values, first=self.index + 30)  # a gap: counted in the same stream
        gap = self.settled_telemetry(lambda t: t.lost_setpoints != lost)
        if (gap.lost_setpoints - lost) & 0xFFFFFFFF != 30:
            raise Broken(f"after ENABLE 1 while enabled, a gap of 30 values counted "
                         f"{(gap.lost_setpoints - lost) & 0xFFFFFFFF} lost: the stream was not kept")
        self.enable(False)
        off = self.telemetry()
        if off.enabled or off.drive_code or off.buffered_setpoints or off.expected_index or off.stream_rate_hz:
            raise Broken(f"after ENABLE 0: enabled {int(off.enabled)}, drive code {off.drive_code}, buffer "
                         f"{off.buffered_setpoints}, expected {off.expected_index}, rate {off.stream_rate_hz}")
        return ("ENABLE 1 while playing kept the stream (playing on, the expected index kept, a gap counted 30 "
                "lost); ENABLE 0 zeroed the drive and forgot the stream")

    def check_discard(self) -> str:
        before = self.telemetry()
        for _ in range(3):
            self.setpoints(self.safe_code, 10)
        refused = self.command(p.SETPOINTS, struct.pack("<IIH", self.index, 1, 1) + b"\0\0")
        if refused is None or refused[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SETPOINTS at 1 setpoint/s while disabled: {_words(refused)}, not NAK 3")
        after = self.settled_telemetry(lambda t: t.discarded_setpoints != before.discarded_setpoints)
        discarded = (after.discarded_setpoints - before.discarded_setpoints) & 0xFFFFFFFF
        if discarded != 30:
            raise Broken(f"30 values sent while disabled, {discarded} counted discarded")
        if not self.v3:
            return "30 values sent while disabled counted discarded; a rate out of range refused (NAK 3)"
        self.enable(True)
        self.quiet(0.06)
        on = self.telemetry()
        if on.buffered_setpoints or on.playback != p.PLAYBACK_PREFILL or on.drive_code:
            raise Broken(f"after ENABLE 1 the values sent while disabled were there: buffer {on.buffered_setpoints}, "
                         f"{p.PLAYBACK_NAMES.get(on.playback)}, drive code {on.drive_code}")
        return "30 values sent while disabled counted discarded, never played; a rate out of range refused (NAK 3)"

    def check_rate(self) -> str:
        other = self.rate * 2 if self.rate * 2 <= self.device.max_setpoint_rate_hz else self.device.min_setpoint_rate_hz
        if other == self.rate:
            raise Unobservable(f"the device plays only {self.rate} setpoints/s: no other rate to try")
        self.enable(True)
        self.stream(0.05, self.safe_code)
        answer = self.command(p.SETPOINTS, struct.pack("<IIH", self.index, other, 1) +
                              struct.pack("<H", self.safe_code))
        if answer is None or answer[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"a frame at {other}/s in a stream at {self.rate}/s: {_words(answer)}, not NAK 3")
        self.enable(False)
        self.enable(True)
        since = self.probe.mark()
        self.stream(0.05, self.safe_code, rate=other)
        refused = [f for _, f in self.probe.received(since, p.NAK)]
        if refused:
            raise Broken(f"after ENABLE 0 and 1, a stream at {other}/s was refused (NAK {refused[0].payload[2]}): "
                         f"the rate of the stream before was kept")
        if self.v3:
            telemetry = self.settled_telemetry(lambda t: t.stream_rate_hz == other)
            if telemetry.stream_rate_hz != other:
                raise Broken(f"a new stream at {other}/s: telemetry says its rate is {telemetry.stream_rate_hz}")
        return f"another rate in a stream refused (NAK 3); after ENABLE 0 and 1 a stream at {other}/s taken"

    def check_prefill(self) -> str:
        self.need_v3()
        self.enable(True)
        self.setpoints(self.safe_code, self.prefill - 1)
        self.quiet(0.06)
        waiting = self.telemetry()
        if waiting.playback != p.PLAYBACK_PREFILL or waiting.drive_code or \
                waiting.buffered_setpoints != self.prefill - 1:
            raise Broken(f"{self.prefill - 1} values buffered of a {self.prefill}-value prefill: "
                         f"{p.PLAYBACK_NAMES.get(waiting.playback)}, buffer {waiting.buffered_setpoints}, drive code "
                         f"{waiting.drive_code} (it must wait, at zero)")
        self.setpoints(self.safe_code, 1)
        started = self.settled_telemetry(lambda t: t.playback in (p.PLAYBACK_PLAYING, p.PLAYBACK_DRY), 5)
        if started.playback not in (p.PLAYBACK_PLAYING, p.PLAYBACK_DRY):
            raise Broken(f"the {self.prefill}th value did not start playback "
                         f"({p.PLAYBACK_NAMES.get(started.playback)})")
        return f"{self.prefill - 1} values waited at zero; the {self.prefill}th started playback"

    def check_expected(self) -> str:
        self.enable(True)
        self.stream(0.05, self.safe_code)
        before = self.telemetry()
        n = self.frame_values
        start = self.index
        self.setpoints(self.safe_code, n, first=start + 20)  # 20 lost
        self.setpoints(self.safe_code, n, first=start + 20 + n - 5)  # 5 behind: 5 late, the rest kept
        self.setpoints(self.safe_code, n, first=start)  # all behind: late; expected stays
        resume = start + 20 + 2 * n - 5
        self.setpoints(self.safe_code, n, first=resume)  # in step, if expected never moved back
        after = self.settled_telemetry(lambda t: t.late_setpoints != before.late_setpoints and
                                       t.lost_setpoints != before.lost_setpoints)
        lost = (after.lost_setpoints - before.lost_setpoints) & 0xFFFFFFFF
        late = (after.late_setpoints - before.late_setpoints) & 0xFFFFFFFF
        if (lost, late) != (20, 5 + n):
            raise Broken(f"a gap of 20, then a frame 5 behind and one wholly behind: {lost} lost and {late} late "
                         f"counted, not 20 and {5 + n}" + (" (expected moved backwards)" if lost > 20 else ""))
        if self.v3 and after.expected_index != (resume + n) & 0xFFFFFFFF:
            raise Broken(f"expected index {after.expected_index}, not {resume + n}")
        return f"a gap of 20 counted lost, a frame 5 behind and one wholly behind counted {5 + n} late, and " \
               "expected never moved back"

    def check_overrun(self) -> str:
        self.enable(True)
        before = self.telemetry()
        chunk = min(p.MAX_SETPOINTS_PER_FRAME, self.capacity)
        frames = math.ceil(1.6 * self.capacity / chunk)
        for _ in range(frames):
            self.setpoints(self.safe_code, chunk)
        sent = frames * chunk
        after = self.settled_telemetry(lambda t: t.fault_counts[OVERRUN] != before.fault_counts[OVERRUN])
        put = (after.setpoints - before.setpoints) & 0xFFFFFFFF
        if not self.v3:
            if put > self.capacity + self.rate // 10:
                raise Broken(f"{sent} values sent at once into a {self.capacity}-value buffer: {put} counted in "
                             "setpoints")
            return f"{sent} values sent at once into a {self.capacity}-value buffer: {put} counted in setpoints"
        dropped = (after.overrun_setpoints - before.overrun_setpoints) & 0xFFFFFFFF
        raised = (after.fault_counts[OVERRUN] - before.fault_counts[OVERRUN]) & 0xFFFFFFFF
        if put + dropped != sent or dropped < sent - self.capacity - self.rate // 10 or not raised:
            raise Broken(f"{sent} values sent at once into a {self.capacity}-value buffer: {put} in setpoints, "
                         f"{dropped} in overrun_setpoints, overrun raised {raised} times")
        return f"{sent} values sent at once into a {self.capacity}-value buffer: {put} in setpoints, {dropped} " \
               f"dropped and counted apart, overrun raised {_times(raised)}"

    def check_underrun(self) -> str:
        self.enable(True)
        before = self.telemetry()
        self.stream(0.15, self.safe_code)
        if self.v3:  # the count from a moment the plate still plays: a hiccup of this host mid-stream is not counted
            self.setpoints(self.safe_code, self.frame_values * 6)
            playing = self.settled_telemetry(lambda t: t.playback == p.PLAYBACK_PLAYING and t.buffered_setpoints, 3)
            if playing.playback == p.PLAYBACK_PLAYING:
                before = playing
            # no values, the watchdog fed, until the plate runs dry by its own clock (a plate that paused counts no
            # time), then a while longer: one dry spell
            since, deadline = self.probe.mark(), time.perf_counter() + 2.0
            while time.perf_counter() < deadline and not any(
                    p.parse_telemetry(f.payload).playback == p.PLAYBACK_DRY
                    for _, f in self.probe.received(since, p.TELEMETRY)):
                self.quiet(0.05)
            self.quiet(0.1)
        else:
            self.quiet(0.25)  # no values, the watchdog fed: a dry spell
        after = self.telemetry()
        raised = (after.fault_counts[UNDERRUN] - before.fault_counts[UNDERRUN]) & 0xFFFFFFFF
        if raised != 1:
            raise Broken(f"a dry spell raised underrun {raised} times, not once")
        if self.v3 and (after.playback != p.PLAYBACK_DRY or abs(after.drive_code - self.safe_code) > 1):
            raise Broken(f"dry: {p.PLAYBACK_NAMES.get(after.playback)}, drive code {after.drive_code} (the last value "
                         f"was {self.safe_code}: it must be held)")
        held = ", and the last value was held" if self.v3 else " (what it held is v3's telemetry: not seen)"
        return "a dry spell raised underrun once" + held

    def check_watchdog(self) -> str:
        watchdog_s = self.device.watchdog_ms / 1000
        self.enable(True)
        before = self.telemetry().fault_counts[WATCHDOG]
        since = self.probe.mark()
        last = self.stream(0.15, self.safe_code)  # the last frame: the silence starts there
        time.sleep(watchdog_s * 4 + 0.1)  # silence: no frame at all
        frames = [(t, p.parse_telemetry(f.payload)) for t, f in self.probe.received(since, p.TELEMETRY)]
        fired = [(k, t) for k, (t, tel) in enumerate(frames) if (tel.fault_counts[WATCHDOG] - before) & 0xFFFFFFFF]
        if not fired:
            raise Broken(f"{1000 * (watchdog_s * 4 + 0.1):.0f} ms without a frame: the watchdog never fired")
        k, seen_at = fired[0]
        count = (frames[-1][1].fault_counts[WATCHDOG] - before) & 0xFFFFFFFF
        earliest, latest = seen_at - last, (frames[k - 1][0] - last) if k else 0.0
        words = f"fired between {1000 * latest:.0f} and {1000 * earliest:.0f} ms of silence"
        # a telemetry frame arrives some time after the device made it: as late as the frames came irregularly
        arrivals = np.diff([t for t, _ in frames])
        delivery = max(0.0, float(arrivals.max()) - 1.0 / p.TELEMETRY_HZ) if len(arrivals) else 0.0
        if earliest < watchdog_s - 0.005:
            raise Broken(f"{words}: before its {self.device.watchdog_ms} ms")
        if latest > watchdog_s + p.WATCHDOG_LATE_MS / 1000 + ANSWER_SLACK_S + delivery:
            raise Broken(f"{words}: more than {p.WATCHDOG_LATE_MS} ms after its {self.device.watchdog_ms} ms")
        if count != 1:
            raise Broken(f"{words}, then {count - 1} more times in the same silence")
        if self.v3 and frames[-1][1].drive_code:
            raise Broken(f"{words}; the drive was still code {frames[-1][1].drive_code} after its ramp")
        lost = frames[-1][1].lost_setpoints
        self.setpoints(self.safe_code, self.frame_values, first=self.index + 50)  # the stream was kept: counted lost
        after = self.settled_telemetry(lambda t: t.lost_setpoints != lost)
        if (after.lost_setpoints - lost) & 0xFFFFFFFF != 50:
            raise Broken(f"{words}; then a frame 50 values on counted {(after.lost_setpoints - lost) & 0xFFFFFFFF} "
                         "lost: the stream was not kept")
        return f"{words} (telemetry every 20 ms), once, ramped to zero, and kept the stream"

    def check_fault_count(self) -> str:
        before = self.telemetry().fault_counts[BAD_COMMAND]
        self.command(0x42)
        self.command(0x42)  # its bit is set now: counted all the same
        after = self.settled_telemetry(lambda t: (t.fault_counts[BAD_COMMAND] - before) & 0xFFFFFFFF >= 2, 3)
        raised = (after.fault_counts[BAD_COMMAND] - before) & 0xFFFFFFFF
        if raised != 2:
            raise Broken(f"two refused frames, the second with bad-command still set: counted {raised} raises")
        return "two refused frames counted two raises of bad-command, the second while its bit was set"

    def check_fault_latch(self) -> str:
        self.command(0x42)
        frames = [self.telemetry() for _ in range(6)]
        clear = [k for k, t in enumerate(frames) if not t.faults & p.FAULT_BAD_COMMAND]
        if clear:
            raise Broken(f"bad-command cleared itself {20 * (clear[0] + 1)} ms after it was raised, no CLEAR_FAULTS "
                         "sent")
        return "bad-command stayed set over 6 telemetry frames until cleared"

    def check_clear_faults(self) -> str:
        self.command(0x42)
        self.enable(True)
        self.setpoints(self.safe_code, self.prefill + 5)
        self.quiet(0.08)  # plays, runs dry: underrun
        self.enable(False)
        both = self.settled_telemetry(lambda t: t.faults & p.FAULT_UNDERRUN and t.faults & p.FAULT_BAD_COMMAND)
        if not (both.faults & p.FAULT_UNDERRUN and both.faults & p.FAULT_BAD_COMMAND):
            raise Unobservable(f"could not raise underrun and bad-command together (faults {both.faults:#06x})")
        self.must(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_BAD_COMMAND), "CLEAR_FAULTS")
        one = self.telemetry()
        if one.faults & p.FAULT_BAD_COMMAND or not one.faults & p.FAULT_UNDERRUN:
            raise Broken(f"CLEAR_FAULTS of bad-command: faults {both.faults:#06x} became {one.faults:#06x}")
        self.must(p.CLEAR_FAULTS, p.clear_faults_payload(p.FAULT_UNDERRUN), "CLEAR_FAULTS")
        if self.telemetry().faults & p.FAULT_UNDERRUN:
            raise Broken("CLEAR_FAULTS of underrun left it set")
        return "CLEAR_FAULTS cleared the bit in its mask and left the other, acknowledged"

    def check_hello_no_state(self) -> str:
        self.need_v3()
        self.enable(True)
        self.stream(0.1, self.safe_code)
        before = self.telemetry()
        answer = self.probe.hello(self.version)
        if answer is None:
            raise Broken("no answer to HELLO while playing")
        self.stream(0.05, self.safe_code)
        after = self.settled_telemetry(lambda t: t.expected_index == self.index, 3)
        changed = []
        if not after.enabled or after.playback not in (p.PLAYBACK_PLAYING, p.PLAYBACK_DRY):
            changed.append(f"the output went {'off' if not after.enabled else p.PLAYBACK_NAMES.get(after.playback)}")
        if after.expected_index != self.index:
            changed.append(f"expected index {after.expected_index}, not the stream's {self.index}")
        if after.frames_ok < before.frames_ok or after.setpoints < before.setpoints:
            changed.append("its counters went back")
        if abs(after.carrier_hz - before.carrier_hz) > 0.01:
            changed.append(f"the carrier moved to {after.carrier_hz:g} Hz")
        if changed:
            raise Broken("HELLO while playing: " + "; ".join(changed))
        return "HELLO while playing changed nothing: still playing, the stream and the counters went on"

    def check_scaling(self) -> str:
        self.need_v3()
        self.enable(True)
        self.stream(0.1, self.safe_code)
        telemetry = self.telemetry()
        if telemetry.playback == p.PLAYBACK_PLAYING and abs(telemetry.drive_code - self.safe_code) > 1:
            raise Broken(f"code {self.safe_code} played as drive code {telemetry.drive_code}")
        d = self.device
        return f"code {self.safe_code} drove {telemetry.drive_code} / 65535 of full scale " \
               f"({telemetry.drive_code / p.SETPOINT_SCALE * d.full_scale_um_pp:.3f} µm p-p of {d.full_scale_um_pp:g})"

    def check_limit(self) -> str:
        self.need_v3()
        d = self.device
        above = min(p.SETPOINT_SCALE, math.ceil(1.25 * self.limit_code))
        if above <= self.limit_code:
            raise Unobservable("the device's limit is its full scale: no code asks for more")
        far = max((d.carrier_min_hz, d.carrier_max_hz), key=lambda f: abs(f - d.resonance_hz))
        self.must(p.SET_CARRIER, p.carrier_payload(far), "SET_CARRIER")
        self.enable(True)
        self.stream(0.15, self.safe_code)
        measured = self.telemetry().measured_um_pp
        gain = self.detuned_gain(far)
        expect = max(measured * above / self.safe_code, gain * above / p.SETPOINT_SCALE * d.full_scale_um_pp)
        if expect > SAFE_FRACTION * self.safe_limit_um_pp:
            raise Unobservable(f"at {far:g} Hz, the carrier farthest from resonance, code {above} would still move "
                               f"the plate {expect:.2f} µm p-p, over 15 % of its limit: not asked")
        since, started = self.probe.mark(), time.perf_counter()
        self.stream(0.2, above)
        drives = [p.parse_telemetry(f.payload).drive_code for t, f in self.probe.received(since, p.TELEMETRY)
                  if t > started + 0.06]  # (brief overdrive, where granted, is over by then)
        worst = max(drives, default=0)
        if not drives:
            raise Broken("no telemetry while asking for more than the limit")
        if worst > self.limit_code + 1:
            raise Broken(f"asked code {above} (1.25 × its limit) at {far:g} Hz: it drove code {worst} "
                         f"({worst / p.SETPOINT_SCALE * d.full_scale_um_pp:.2f} µm p-p of drive, its limit "
                         f"{d.max_amplitude_um_pp:g})")
        return (f"asked code {above} (1.25 × its limit) at {far:g} Hz, off resonance (the plate moved under "
                f"{expect:.2f} µm p-p): it drove at most code {worst}, its limit's {self.limit_code}")

    def detuned_gain(self, carrier_hz: float) -> float:
        """The plate's steady gain at ``carrier_hz`` by the profile's resonance and Q (for a device that does not
        measure its amplitude), at least the device's own resonance's."""
        q, f0 = self.profile.q, self.device.resonance_hz
        return 1.0 / math.sqrt(1.0 + (2.0 * q * (carrier_hz - f0) / f0) ** 2)

    def check_over_limit(self) -> str:
        if not self.over_limit:
            raise Unobservable("needs the plate above its limit (ask for it with --over-limit, on a plate that "
                               "can take 1 % over its limit for a moment)")
        return self.drive_at_limit("R-OVER-LIMIT")

    def check_trip(self) -> str:
        if not self.over_limit:
            raise Unobservable("needs the plate more than 1 % above its limit (--over-limit)")
        return self.drive_at_limit("R-TRIP")

    def drive_at_limit(self, rule: str) -> str:
        """Drive at the device's limit for 0.4 s: a plate stronger than the device believes goes over it."""
        self.need_v3()
        d = self.device
        if self.profile.max_amplitude_um_pp < d.max_amplitude_um_pp:
            raise Unobservable(f"the profile {self.profile.name}'s limit, {self.profile.max_amplitude_um_pp:g} µm p-p, "
                               f"is below the plate driver's {d.max_amplitude_um_pp:g}: not driven past it")
        self.probe.abort_um_pp = d.max_amplitude_um_pp * 1.05
        try:
            self.enable(True)
            before = self.telemetry()
            since = self.probe.mark()
            self.stream(0.4, self.limit_code)
            frames = [p.parse_telemetry(f.payload) for _, f in self.probe.received(since, p.TELEMETRY)]
        finally:  # at rest again before the check's own bound comes back: the plate rings down, telemetry lags
            self.probe.send(p.ENABLE, p.enable_payload(False))
            self.settled_telemetry(lambda t: t.measured_um_pp <= ABORT_FRACTION * self.safe_limit_um_pp)
            self.probe.abort_um_pp = ABORT_FRACTION * self.safe_limit_um_pp
        peak = max((t.measured_um_pp for t in frames), default=0.0)
        over = (frames[-1].fault_counts[OVER_LIMIT] - before.fault_counts[OVER_LIMIT]) & 0xFFFFFFFF
        trips = (frames[-1].fault_counts[TRIP] - before.fault_counts[TRIP]) & 0xFFFFFFFF
        limit = d.max_amplitude_um_pp
        if peak <= limit and not over and not trips:
            raise Unobservable(f"driven at its limit the plate measured {peak:.3f} µm p-p, not above "
                               f"{limit:g}: nothing to see")
        if rule == "R-OVER-LIMIT":
            went = f"went to {peak:.3f} µm p-p, over its {limit:g} limit" if peak > limit else \
                f"went over its {limit:g} limit (and tripped before telemetry showed it)"
            if over != 1:
                raise Broken(f"the plate {went} once: over-limit raised {over} times")
            return f"the plate {went}: over-limit raised once"
        if peak <= limit * (1 + p.TRIP_MARGIN) and not trips:
            raise Unobservable(f"the plate went to {peak:.3f} µm p-p, not 1 % over its limit {limit:g}")
        if trips != 1 or frames[-1].enabled:
            raise Broken(f"the plate went to {peak:.3f} µm p-p, over its trip at {limit * 1.01:.3f}: trip raised "
                         f"{trips} times, output {'on' if frames[-1].enabled else 'off'}")
        return "the plate went over 1.01 × its limit: trip raised, output cut and disabled"

    def check_sensors(self) -> str:
        d = self.device
        if not self.v3 or not getattr(d, "sensors", 0):
            raise Unobservable("the device has no sensor" if self.v3 else "SENSORS are v3's")
        # a device whose link cannot drain what it sends (a slow UART, an emulator or this host on a loaded machine)
        # loses a whole frame now and then: a gap at a few frame boundaries. A device that leaves samples out, or
        # repeats them, does it at most of them.
        since = self.probe.mark()
        time.sleep(0.3)  # disabled
        self.enable(True)
        enabled_from = time.perf_counter()
        self.stream(0.3, self.safe_code)
        frames = [(t, p.parse_sensors(f.payload)) for t, f in self.probe.received(since, p.SENSORS)]
        if len(frames) < 5:
            raise Broken(f"{len(frames)} SENSORS frames in 0.6 s")
        steps = [((b.first_sample - a.first_sample) & 0xFFFFFFFF) - len(a.samples)
                 for (_, a), (_, b) in zip(frames, frames[1:], strict=False)]
        wrong = [step for step in steps if step]
        repeated = [step for step in wrong if step > 0x7FFFFFFF]
        smallest = min(len(s.samples) for _, s in frames)  # a lost frame leaves out at least this many
        if repeated or len(wrong) > max(1, len(steps) // 10) or any(step < smallest for step in wrong):
            k = next(k for k, step in enumerate(steps) if step)
            a, b = frames[k][1], frames[k + 1][1]
            raise Broken(f"{'samples repeated' if repeated else 'samples left out'} between {len(wrong)} of "
                         f"{len(steps)} frames (a frame from sample {a.first_sample} of {len(a.samples)} samples, "
                         f"the next from {b.first_sample})")
        first_gap = f"{len(wrong)} gap{'s' if len(wrong) > 1 else ''} of {', '.join(map(str, wrong))} samples" \
            if wrong else ""
        # how often, on the device's own clock: a frame every 10 ms carries 10 ms of samples (+1: the millisecond it
        # is made in) on average, every 50 ms at rest; none carries twice that (a frame left out). A frame begun
        # before ENABLE may carry the rest's.
        rate = d.sensor_rate_hz
        on = [len(s.samples) for (a, _), (_, s) in zip(frames, frames[1:], strict=False) if a > enabled_from + 0.02]
        off = [len(s.samples) for t, s in frames if t < enabled_from]
        words = (f"SENSORS frames of {np.mean(on) if on else 0:.1f} samples on average (at most {max(on, default=0)}) "
                 f"while enabled, {np.mean(off) if off else 0:.1f} (at most {max(off, default=0)}) at rest, at {rate} "
                 "samples a second")
        for sizes, period_ms in ((on, p.SENSORS_PERIOD_MS), (off, p.SENSORS_REST_PERIOD_MS)):
            per_period = rate * period_ms / 1000
            if sizes and (np.mean(sizes) > per_period + 1 or max(sizes) > 2 * per_period):
                raise Broken(f"{words}: sent less often than every {p.SENSORS_PERIOD_MS} ms (enabled) or "
                             f"{p.SENSORS_REST_PERIOD_MS} ms (at rest)")
        samples = sum(len(s.samples) for _, s in frames)
        lost = f" ({first_gap} between {len(steps)} frames: whole frames lost on the way, the link or this host " \
            "falling behind)" if first_gap else ""
        return f"{len(frames)} frames, {samples} samples, consecutive{lost}; {words}"

    def check_loop(self) -> str:
        has_loop = self.v3 and self.device.features & p.FEATURE_AMPLITUDE_LOOP
        if not has_loop:
            answer = self.command(p.SET_LOOP, p.set_loop_payload(1))
            if answer is None or answer[:2] != ("nak", p.NAK_UNSUPPORTED):
                raise Broken(f"SET_LOOP 1 on a device without the loop (or a v2 session): {_words(answer)}, not "
                             "NAK 4")
            return "no amplitude loop: SET_LOOP refused with NAK 4"
        self.enable(True)
        while_on = self.command(p.SET_LOOP, p.set_loop_payload(1))
        self.enable(False)
        if while_on is None or while_on[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_LOOP 1 while enabled: {_words(while_on)}, not NAK 3")
        other = self.command(p.SET_LOOP, bytes([2]))
        if other is None or other[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_LOOP 2: {_words(other)}, not NAK 3")
        self.must(p.SET_LOOP, p.set_loop_payload(1), "SET_LOOP 1 while disabled")
        mode = self.telemetry().loop
        self.must(p.SET_LOOP, p.set_loop_payload(0), "SET_LOOP 0")
        if mode != 1:
            raise Broken(f"SET_LOOP 1 acknowledged; telemetry says loop {mode}")
        return "SET_LOOP refused while enabled and for mode 2 (NAK 3); taken while disabled, and telemetry said so"


def _times(count: int) -> str:
    return "once" if count == 1 else f"{count} times"


def _words(answer) -> str:
    if answer is None:
        return "no answer"
    return "ACK" if answer[0] == "ack" else f"NAK {answer[1]}"


def _cobs_decode(data: bytes) -> bytes:
    from cobs import cobs

    return cobs.decode(bytes(data))


def _cobs_encode(body: bytes) -> bytes:
    from cobs import cobs

    return cobs.encode(body) + b"\x00"


def check_device(port: str, profile: PlateProfile, baudrate: int = 921600, over_limit: bool = False,
                 say=None, heading=None, hold=None, only: tuple[str, ...] = ()) -> CheckReport:
    """Open ``port`` (exclusively), run every rule (or ``only`` those named), rest the plate; ``heading(line)``
    once the device has described itself, ``say(verdict)`` as each rule's is known; ``hold()`` is a context in
    which a stop signal waits (the rest at the end runs in it)."""
    unknown = [rule for rule in only if rule not in RULES]
    if unknown:
        raise DeviceError(f"no rule {', '.join(unknown)}; the rules are {', '.join(RULES)}")
    probe = Probe(port, baudrate)
    try:
        return Check(probe, profile, over_limit, say, heading, hold, only).run()
    finally:
        probe.close()
