"""plate check's rules of the link: telemetry, seqs, answers, version, CRC, framing and NAKs."""

from __future__ import annotations

import math
import struct
import time

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.conformance.probe import (
    ANSWER_SLACK_S,
    BAD_COMMAND,
    TIMEOUT_S,
    WATCHDOG,
    Broken,
    answer_words,
    cobs_decode,
    cobs_encode,
)
from ultraglide.devices.protocol.ranges import telemetry_out_of_range


class LinkRules:
    """The link's rules: a part of :class:`~ultraglide.devices.conformance.check.Check`."""

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
        if self.device is not None:  # every field within what it can be (devices/protocol/ranges.py)
            for _, frame in self.probe.received(since, p.TELEMETRY):
                impossible = telemetry_out_of_range(p.parse_telemetry(frame.payload), self.device)
                if impossible:
                    raise Broken("TELEMETRY with values that cannot be: " + "; ".join(words for _, words in impossible))
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
            raise Broken(f"CLEAR_FAULTS sent with seq 0xbeef: {answer_words(ack)}{named}")
        if nak is None or nak[0] != "nak" or nak[3] != 0x1234:
            named = f", naming {nak[3]:#06x}" if nak else ""
            raise Broken(f"type 0x42 sent with seq 0x1234: {answer_words(nak)}{named}")
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
        body = bytearray(cobs_decode(frame[:-1]))
        body[-1] ^= 0x5A  # the CRC's last byte
        since = self.probe.mark()
        self.probe.send_bytes(cobs_encode(bytes(body)))
        if self.probe.answer(0x7777, since, 0.2) is not None:
            raise Broken("a frame with a bad CRC was answered")
        after = self.settled_telemetry(lambda t: t.crc_errors != before.crc_errors)
        if (after.crc_errors - before.crc_errors) & 0xFFFFFFFF != 1:
            raise Broken(f"crc_errors went up by {(after.crc_errors - before.crc_errors) & 0xFFFFFFFF}, not 1")
        # and bad frames feed no watchdog: a stream, then only frames with bad CRCs
        self.enable(True)
        self.stream(0.1, self.safe_code)
        watchdogs = self.counts()[WATCHDOG]
        bad = bytearray(cobs_decode(p.encode_frame(p.HEARTBEAT, 1)[:-1]))
        bad[-1] ^= 0x5A
        for _ in range(int(4.5 * self.device.watchdog_ms / 20)):
            self.probe.send_bytes(cobs_encode(bytes(bad)))
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
            raise Broken(f"a frame of {p.MAX_BODY} decoded bytes (type 0x42) was not taken: {answer_words(answer)}, "
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
                raise Broken(f"{name}: {answer_words(answer)}, not NAK {reason}")
            seen.append(f"NAK {reason} for {name}")
        # NAK 4: SET_LOOP of the wrong length where the loop is not supported (a v2 session, or no loop)
        hello = self.probe.hello(2)
        session = hello[0].version if hello and hello[0] else self.version
        unsupported = session < 3 or not self.device.features & p.FEATURE_AMPLITUDE_LOOP
        answer = self.command(p.SET_LOOP, b"\x00\x00")
        self.probe.hello(self.version)
        wanted = self.unsupported_naks if unsupported else (p.NAK_BAD_LENGTH,)
        if answer is None or answer[0] != "nak" or answer[1] not in wanted:
            expected = self.unsupported_words() if unsupported else f"NAK {p.NAK_BAD_LENGTH}"
            raise Broken(f"SET_LOOP of 2 bytes in a v{session} session: {answer_words(answer)}, not {expected}")
        seen.append(f"NAK {answer[1]} for SET_LOOP of 2 bytes in a v{session} session"
                    + (" (a device whose highest version is v2: SET_LOOP is not in its table)"
                       if answer[1] == p.NAK_UNKNOWN_TYPE else ""))
        return "; ".join(seen) + " (NAK 5 needs a failing handler: not provoked)"

    def check_nak_no_effect(self) -> str:
        before = self.telemetry()
        wrong = self.device.carrier_max_hz + 500.0
        answer = self.command(p.SET_CARRIER, p.carrier_payload(wrong))
        if answer is None or answer[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_CARRIER {wrong:g} Hz, above the range: {answer_words(answer)}, not NAK 3")
        after = self.telemetry()
        raised = (after.fault_counts[BAD_COMMAND] - before.fault_counts[BAD_COMMAND]) & 0xFFFFFFFF
        if abs(after.carrier_hz - before.carrier_hz) > 0.01:
            raise Broken(f"a refused SET_CARRIER {wrong:g} Hz moved the carrier from {before.carrier_hz:g} to "
                         f"{after.carrier_hz:g} Hz")
        if raised != 1:
            raise Broken(f"a refused frame raised bad-command {raised} times, not once")
        return f"SET_CARRIER {wrong:g} Hz refused (NAK 3), the carrier stayed at {after.carrier_hz:g} Hz, " \
               "bad-command raised once"
