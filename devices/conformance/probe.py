"""``plate check``'s ground: its constants, verdicts and report, and the probe that speaks the protocol
frame by frame (the seq it chooses, the bytes it wants, every answer timed)."""

from __future__ import annotations

import math
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.serial.link import FrameWriter, open_port

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
    "R-LOOP": "The amplitude loop", "R-FORCE": "The force correction", "R-CLOCK": "Device → host",
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
                           "carrier_max_hz": d.carrier_max_hz, "watchdog_ms": d.watchdog_ms, "buffer_ms": d.buffer_ms,
                           "last_started": d.restart_words()},  # why it last started, in words (None: not stated)
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
        self.writer = FrameWriter(self.serial, WRITE_TIMEOUT_S)  # as the engine writes: no poll after a whole write
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
        """``data`` written whole (:class:`.link.FrameWriter`: the port is polled only when the kernel takes part of
        it, within ``WRITE_TIMEOUT_S``); Abort if the port failed or took no byte for that long."""
        with self._write_lock:
            try:
                self.writer.write(data)
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


def times_words(count: int) -> str:
    return "once" if count == 1 else f"{count} times"


def answer_words(answer) -> str:
    if answer is None:
        return "no answer"
    return "ACK" if answer[0] == "ack" else f"NAK {answer[1]}"


def cobs_decode(data: bytes) -> bytes:
    from cobs import cobs

    return cobs.decode(bytes(data))


def cobs_encode(body: bytes) -> bytes:
    from cobs import cobs

    return cobs.encode(body) + b"\x00"
