"""A plate driver that misbehaves as a test scripts it, on a real pseudo-terminal: for the host's error paths
that the simulated plate (which follows the protocol) never takes. It answers HELLO with a v2 reply (or a NAK,
or nothing), answers each command with ACK, NAK or silence as told, sends TELEMETRY 50 times a second with
the latched faults it is given, and records every frame it decodes, in order.

    with ScriptedPlate(answers={p.ENABLE: {1: "nak"}}) as plate:   # refuses ENABLE 1, ACKs ENABLE 0
        ... SerialPlate(plate.path, profile) ...
        plate.frames   # [(kind, payload), ...]
"""

import os
import select
import threading
import time
import tty

from ultraglide.devices import protocol as p
from ultraglide.devices.profiles import load_profile

PROFILE = load_profile("sim-plate")


class ScriptedPlate:
    """``hello``: "reply", "nak" or None (no answer). ``answers``: command → "ack", "nak", None (no answer), or a
    dict from the payload's first byte to one of those. ``faults``: latched fault bits in telemetry, each counted
    once. ``telemetry``: send it (50 a second) or not."""

    def __init__(self, hello="reply", answers=None, faults=0, telemetry=True, limit_um_pp=None, counts=None,
                 frames_ok=None, enabled_follows=False):
        """``counts``: a function of the telemetry frame's number giving its 8 fault counters (a lying plate's);
        ``frames_ok``: likewise for its frames_ok (default: the frames it decoded); ``enabled_follows``: telemetry's
        ``enabled`` is the last ENABLE it acknowledged (else always 0)."""
        self.enabled_follows = enabled_follows
        self.enabled = False
        self.counts = counts
        self.frames_ok = frames_ok
        self.sent_telemetry = 0
        self.hello = hello
        self.answers = answers or {}
        self.faults = faults
        self.telemetry = telemetry
        self.limit_um_pp = limit_um_pp or PROFILE.max_amplitude_um_pp
        self.frames: list[tuple[int, bytes]] = []
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        os.close(slave)
        self._seq = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=5)
        os.close(self.master)

    def kinds(self, kind) -> list[bytes]:
        """The payloads of the frames of one kind received so far."""
        return [payload for k, payload in list(self.frames) if k == kind]

    def _send(self, kind, payload):
        self._seq = (self._seq + 1) & 0xFFFF
        try:
            os.write(self.master, p.encode_frame(kind, self._seq, payload))
        except OSError:  # nobody has the port open: what a UART does, drop it
            pass

    def _answer(self, frame):
        if frame.kind == p.HELLO:
            if self.hello == "reply":
                reply = p.HelloReply(2, PROFILE.resonance_hz, PROFILE.full_scale_um_pp, self.limit_um_pp, 1000, 48000,
                                     PROFILE.carrier_min_hz, PROFILE.carrier_max_hz, 100, 250, "scripted plate")
                self._send(p.HELLO_REPLY, p.hello_reply_payload(reply))
            elif self.hello == "nak":
                self._send(p.NAK, p.nak_payload(frame.seq, p.NAK_UNKNOWN_TYPE))
            return
        answer = self.answers.get(frame.kind, "ack" if frame.kind not in (p.SETPOINTS, p.HEARTBEAT) else None)
        if isinstance(answer, dict):
            answer = answer.get(frame.payload[0] if frame.payload else None, "ack")
        if answer == "ack":
            if frame.kind == p.ENABLE and self.enabled_follows and frame.payload:
                self.enabled = frame.payload[0] == 1
            self._send(p.ACK, p.ack_payload(frame.seq))
        elif answer == "nak":
            self._send(p.NAK, p.nak_payload(frame.seq, p.NAK_UNKNOWN_TYPE))

    def _telemetry(self, frames_ok):
        counts = tuple(1 if self.faults & (1 << bit) else 0 for bit in range(p.FAULT_BITS))
        if self.counts is not None:
            counts = tuple(self.counts(self.sent_telemetry))
        if self.frames_ok is not None:
            frames_ok = self.frames_ok(self.sent_telemetry)
        self.sent_telemetry += 1
        values = p.Telemetry(0.0, PROFILE.resonance_hz, self.faults, self.enabled, frames_ok, 0, 0, 0, 0, 0, 0, counts)
        try:
            payload = p.telemetry_payload(values, 2)  # a v2 device's layout
        except TypeError:  # (a protocol module that writes v2's only)
            payload = p.telemetry_payload(values)
        self._send(p.TELEMETRY, payload)

    def _serve(self):
        decoder = p.FrameDecoder()
        next_telemetry = time.monotonic()
        while not self._stop.is_set():
            if self.telemetry and time.monotonic() >= next_telemetry:
                self._telemetry(decoder.frames)
                next_telemetry += 1.0 / p.TELEMETRY_HZ
            if not select.select([self.master], [], [], 0.005)[0]:
                continue
            try:
                data = os.read(self.master, 65536)
            except OSError:  # nobody has the port open
                time.sleep(0.005)
                continue
            for frame in decoder.feed(data):
                self.frames.append((frame.kind, frame.payload))
                self._answer(frame)
