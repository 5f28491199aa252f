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
import time
from collections.abc import Callable

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.conformance.device import DeviceRules
from ultraglide.devices.conformance.link import LinkRules
from ultraglide.devices.conformance.probe import (
    ABORT_FRACTION,
    ANSWER_SLACK_S,
    FAIL,
    NOT_CHECKED,
    PASS,
    RETRIES,
    RULES,
    SAFE_FRACTION,
    SILENCE_S,
    Abort,
    Broken,
    CheckReport,
    Probe,
    Unobservable,
    Verdict,
)
from ultraglide.devices.conformance.stream import StreamRules
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile


# ---- the check -------------------------------------------------------------------------------------------
class Check(LinkRules, StreamRules, DeviceRules):
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

    @property
    def unsupported_naks(self) -> tuple[int, ...]:
        """The NAK reasons a device may give v3's SET_LOOP and SETPOINTS_FORCE where it does not do them, judged by
        the highest version it speaks (its answer to HELLO 3): NAK 4 from a v3 device; from a device whose highest
        version is v2, NAK 1 as well (v2's table has no such types: unknown) or NAK 4 (a v3 core held to v2)."""
        if self.device is not None and self.device.version >= 3:
            return (p.NAK_UNSUPPORTED,)
        return (p.NAK_UNKNOWN_TYPE, p.NAK_UNSUPPORTED)

    def unsupported_words(self) -> str:
        """``NAK 4``, or ``NAK 1 or 4`` for a device whose highest version is v2."""
        return " or ".join(str(reason) for reason in self.unsupported_naks).join(("NAK ", ""))

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
                f"{bound} {self.safe_limit_um_pp:g} µm p-p limit) at {self.carrier:g} Hz"
                + (f"; why it last started: {d.restart_words()}" if d.restart_words() else ""))

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
            ("R-SENSORS", self.check_sensors), ("R-CLOCK", self.check_clock), ("R-LOOP", self.check_loop),
            ("R-FORCE", self.check_force),
            ("R-RATE", self.check_rate),  # last: a device that keeps a stream's rate would refuse every rule after
        ]


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
