"""plate check's rules of the stream: carrier, enable, the jitter buffer, watchdog and faults."""

from __future__ import annotations

import math
import struct
import time

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.conformance.probe import (
    ANSWER_SLACK_S,
    BAD_COMMAND,
    OVERRUN,
    UNDERRUN,
    WATCHDOG,
    Broken,
    Unobservable,
    answer_words,
    times_words,
)


class StreamRules:
    """The stream's rules: a part of :class:`~ultraglide.devices.conformance.check.Check`."""

    def check_carrier(self) -> str:
        d = self.device
        other = min(d.carrier_max_hz, self.carrier + 100.0) if self.carrier + 100.0 <= d.carrier_max_hz else \
            max(d.carrier_min_hz, self.carrier - 100.0)
        self.enable(True)
        self.stream(0.1, self.safe_code)
        answer = self.command(p.SET_CARRIER, p.carrier_payload(other))
        if answer is None or answer[0] != "ack":
            raise Broken(f"SET_CARRIER {other:g} Hz while enabled: {answer_words(answer)}, not ACK")
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
            raise Broken(f"SETPOINTS at 1 setpoint/s while disabled: {answer_words(refused)}, not NAK 3")
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
            raise Broken(f"a frame at {other}/s in a stream at {self.rate}/s: {answer_words(answer)}, not NAK 3")
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
               f"dropped and counted apart, overrun raised {times_words(raised)}"

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
