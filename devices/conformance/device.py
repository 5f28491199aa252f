"""plate check's rules of the device: HELLO, scaling, limits, trip, sensors and the loop."""

from __future__ import annotations

import math
import time

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.conformance.probe import (
    ABORT_FRACTION,
    ANSWER_SLACK_S,
    OVER_LIMIT,
    SAFE_FRACTION,
    TIMEOUT_S,
    TRIP,
    Broken,
    Unobservable,
    answer_words,
)
from ultraglide.devices.serial.follow import FOLLOW_FACTOR

CLOCK_ASKED = 20  # [R-CLOCK]: CLOCK requests, one at a time, CLOCK_GAP_S apart
CLOCK_GAP_S = 0.02
SETTLE_WAIT_S = 0.5  # after a stream, how long [R-LIMIT] waits for telemetry of the device 60 ms into its codes
LIMIT_TRIES = 3  # [R-LIMIT]'s streams before it says the device was never seen playing them

class DeviceRules:
    """The device's rules: a part of :class:`~ultraglide.devices.conformance.check.Check`."""

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
        sent_um_pp = self.safe_code / p.SETPOINT_SCALE * d.full_scale_um_pp
        measured = ""
        if d.sensors & p.SENSOR_AMPLITUDE and telemetry.playback == p.PLAYBACK_PLAYING:
            # its measured amplitude follows the code: within devices/serial/follow.py's bound (1/3 to 3 times),
            # at resonance, 0.1 s into a steady code (the plate settles within its time constant, ms)
            low, high = sent_um_pp / FOLLOW_FACTOR, sent_um_pp * FOLLOW_FACTOR
            if not low <= telemetry.measured_um_pp <= high:
                raise Broken(f"the plate does not follow the amplitude: code {self.safe_code} ({sent_um_pp:.3f} "
                             f"µm p-p of full scale {d.full_scale_um_pp:g}) measured {telemetry.measured_um_pp:.3f} "
                             f"µm p-p, outside {low:.3f}..{high:.3f} (1/{FOLLOW_FACTOR:g} to {FOLLOW_FACTOR:g} times)")
            measured = f"; measured {telemetry.measured_um_pp:.3f} µm p-p (within 1/{FOLLOW_FACTOR:g} to " \
                       f"{FOLLOW_FACTOR:g} times)"
        return f"code {self.safe_code} drove {telemetry.drive_code} / 65535 of full scale " \
               f"({telemetry.drive_code / p.SETPOINT_SCALE * d.full_scale_um_pp:.3f} µm p-p of " \
               f"{d.full_scale_um_pp:g}){measured}"

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
        # judged on the device's own timeline: the value it plays (the next it expects, less those it holds)
        # 60 ms or more into these codes (brief overdrive, where granted, is over by then), however late a loaded
        # machine or an emulator delivers its frames. A pass needs the device seen playing them there: a device
        # whose buffer ran dry (this host's frames came late, or all were played) holds a value of its own, and a
        # simulator that stalled sends one frame for the whole stall, so the codes may go unseen: asked again
        settled = round(0.06 * self.rate)
        for _ in range(LIMIT_TRIES):
            since, first = self.probe.mark(), self.index
            self.stream(0.2, above)
            # a device whose frames came late, or whose clock fell behind this host's (an emulator's does), is still
            # playing them (its buffer holds the cushion): its telemetry until it is 60 ms in, HEARTBEAT feeding it
            deadline = time.perf_counter() + SETTLE_WAIT_S
            while not self.playing_codes(since, first + settled) and time.perf_counter() < deadline:
                self.telemetry()
            into = self.telemetry_from(since, first + settled)
            worst = max((t.drive_code for t in into), default=0)  # a value held over the limit counts too
            if worst > self.limit_code + 1:
                raise Broken(f"asked code {above} (1.25 × its limit) at {far:g} Hz: it drove code {worst} "
                             f"({worst / p.SETPOINT_SCALE * d.full_scale_um_pp:.2f} µm p-p of drive, its limit "
                             f"{d.max_amplitude_um_pp:g})")
            if self.playing_codes(since, first + settled):
                return (f"asked code {above} (1.25 × its limit) at {far:g} Hz, off resonance (the plate moved under "
                        f"{expect:.2f} µm p-p): it drove at most code {worst}, its limit's {self.limit_code}")
        raise Unobservable(f"asked code {above} {LIMIT_TRIES} times: the device's telemetry never showed it playing "
                           f"them 60 ms in (this machine or the device too busy to keep the stream going)")

    def telemetry_from(self, since: int, index: int) -> list[p.Telemetry]:
        """The TELEMETRY frames received since the probe's mark ``since`` of a device that had played up to the
        stream's ``index`` (its next expected less those it holds; on its own timeline, as a 32-bit counter)."""
        frames = [p.parse_telemetry(f.payload) for _, f in self.probe.received(since, p.TELEMETRY)]
        return [t for t in frames if (t.expected_index - t.buffered_setpoints - index) & 0xFFFFFFFF < 2 ** 31]

    def playing_codes(self, since: int, index: int) -> list[int]:
        """The drive codes of :meth:`telemetry_from`'s frames sent while the device played its stream (not
        prefilling, dry or ramping)."""
        return [t.drive_code for t in self.telemetry_from(since, index) if t.playback == p.PLAYBACK_PLAYING]

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
            self.probe.telemetry(since)  # at least one frame of the drive, however late this host's reader got to it
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

    def check_clock(self) -> str:
        d = self.device
        if not (self.v3 and d.features & p.FEATURE_CLOCK_STATED):
            # NAK 1 whatever the version: a v3 device built before CLOCK (0x09) existed does not know the type
            answer = self.command(p.CLOCK)
            if answer is None or answer[0] != "nak" or answer[1] not in (p.NAK_UNKNOWN_TYPE, p.NAK_UNSUPPORTED):
                raise Broken(f"CLOCK on a device that does not state its clock (or a v2 session): "
                             f"{answer_words(answer)}, not NAK 1 or 4")
            before = " (a device built before CLOCK: not in its table)" if answer[1] == p.NAK_UNKNOWN_TYPE else ""
            return f"no clock stated: CLOCK refused with NAK {answer[1]}{before}"
        # The device had taken the samples of every SENSORS frame read before a request was written before it took
        # the request: its clock then is at least their end, less MAX_CLOCK_LAG_MS. Judged on the device's own
        # numbers, not this host's clock (an emulated board's clock is not steady against it: QEMU's stalls and its
        # instruction counter's pace). Enabled (nothing played: no setpoint is sent), its SENSORS leave every 10 ms;
        # the requests feed its watchdog.
        rate, probe = d.sensor_rate_hz, self.probe
        self.enable(True)
        since = probe.mark()
        replies, slowest = [], 0.0
        for _ in range(CLOCK_ASKED):
            mark = probe.mark()
            asked = time.perf_counter()
            seq, _ = probe.send(p.CLOCK)
            found = probe.wait(lambda f: f.kind == p.CLOCK_REPLY, mark, TIMEOUT_S)
            if found is None:
                raise Broken(f"CLOCK: no CLOCK_REPLY within {TIMEOUT_S:g} s")
            t, frame, _ = found
            try:
                reply = p.parse_clock_reply(frame.payload)
            except p.ProtocolError as error:
                raise Broken(f"CLOCK: {error}") from None
            if reply.asked_seq != seq:
                raise Broken(f"CLOCK_REPLY names seq {reply.asked_seq}, not the request's {seq}")
            replies.append((asked, t, reply))
            slowest = max(slowest, t - asked)
            time.sleep(CLOCK_GAP_S)
        self.enable(False)
        frames = [(t, p.parse_sensors(f.payload)) for t, f in probe.received(since, p.SENSORS)]
        reference = replies[0][2].sample

        def unwrapped(sample: int) -> float:
            return float((sample - reference + 2**31) % 2**32 - 2**31)

        stated = [unwrapped(reply.sample) + reply.fraction / 65536.0 for _, _, reply in replies]
        if any(b < a for a, b in zip(stated, stated[1:], strict=False)):
            raise Broken(f"CLOCK_REPLY's clock went back: {', '.join(f'{c:.2f}' for c in stated[:6])} samples "
                         "from the first")
        lag = p.MAX_CLOCK_LAG_MS * rate / 1000.0
        margins = []  # each reply's clock past the end of the SENSORS read before its request, samples
        for (asked, _, _), clock in zip(replies, stated, strict=True):
            before = [unwrapped(s.first_sample) + len(s.samples) for t, s in frames if t < asked]
            if before:
                margins.append(clock - max(before))
        if not margins:
            raise Broken("no SENSORS frame came while CLOCK was asked (enabled, one is due every 10 ms)")
        if min(margins) < -lag - 1e-6:
            raise Broken(f"CLOCK_REPLY's clock is more than {p.MAX_CLOCK_LAG_MS} ms behind the device's: "
                         f"{-min(margins):.2f} samples before the end of a SENSORS frame it had sent before the "
                         f"request ({rate} samples a second)")
        if slowest > p.ACK_DEADLINE_MS / 1000 + ANSWER_SLACK_S:
            raise Broken(f"CLOCK answered in up to {1000 * slowest:.1f} ms, more than {p.ACK_DEADLINE_MS} ms")
        fastest = min(t - asked for asked, t, _ in replies)
        return (f"{len(replies)} CLOCK replies, each naming its request, in {1000 * fastest:.2f}-"
                f"{1000 * slowest:.2f} ms; their clock never went back, and lay {min(margins):.2f} to "
                f"{max(margins):.2f} samples past the SENSORS sent before each request (at most "
                f"{p.MAX_CLOCK_LAG_MS} ms behind them is allowed)")

    def check_force(self) -> str:
        def frame(force_n: float, exponent: float) -> bytes:  # zeros, sent while disabled: discarded if taken
            return p.setpoints_force_payload(self.index, self.rate, np.zeros(self.frame_values),
                                             p.ForceReference(force_n, exponent, 0.0))

        if not (self.v3 and self.device.features & p.FEATURE_FORCE_CORRECTION):
            answer = self.command(p.SETPOINTS_FORCE, frame(0.5, 1.0 / 3.0))
            if answer is None or answer[0] != "nak" or answer[1] not in self.unsupported_naks:
                raise Broken(f"SETPOINTS_FORCE on a device without the force correction (or a v2 session): "
                             f"{answer_words(answer)}, not {self.unsupported_words()}")
            return f"no force correction: SETPOINTS_FORCE refused with NAK {answer[1]}{_v2_words(answer[1])}"
        for force_n, exponent, what in ((0.0, 1.0 / 3.0, "a force of 0 N"), (math.nan, 1.0 / 3.0, "a force NaN"),
                                        (0.5, 2.5, "an exponent of 2.5")):
            answer = self.command(p.SETPOINTS_FORCE, frame(force_n, exponent))
            if answer is None or answer[:2] != ("nak", p.NAK_BAD_VALUE):
                raise Broken(f"SETPOINTS_FORCE with {what}: {answer_words(answer)}, not NAK 3")
        answer = self.command(p.SETPOINTS_FORCE, frame(0.5, 1.0 / 3.0))
        if answer is not None:
            raise Broken(f"SETPOINTS_FORCE with 0.5 N and an exponent of 1/3: {answer_words(answer)}, not taken")
        return "references out of range refused (NAK 3), one in range taken"

    def check_loop(self) -> str:
        has_loop = self.v3 and self.device.features & p.FEATURE_AMPLITUDE_LOOP
        if not has_loop:
            answer = self.command(p.SET_LOOP, p.set_loop_payload(1))
            if answer is None or answer[0] != "nak" or answer[1] not in self.unsupported_naks:
                raise Broken(f"SET_LOOP 1 on a device without the loop (or a v2 session): {answer_words(answer)}, not "
                             f"{self.unsupported_words()}")
            return f"no amplitude loop: SET_LOOP refused with NAK {answer[1]}{_v2_words(answer[1])}"
        self.enable(True)
        while_on = self.command(p.SET_LOOP, p.set_loop_payload(1))
        self.enable(False)
        if while_on is None or while_on[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_LOOP 1 while enabled: {answer_words(while_on)}, not NAK 3")
        other = self.command(p.SET_LOOP, bytes([2]))
        if other is None or other[:2] != ("nak", p.NAK_BAD_VALUE):
            raise Broken(f"SET_LOOP 2: {answer_words(other)}, not NAK 3")
        self.must(p.SET_LOOP, p.set_loop_payload(1), "SET_LOOP 1 while disabled")
        mode = self.telemetry().loop
        self.must(p.SET_LOOP, p.set_loop_payload(0), "SET_LOOP 0")
        if mode != 1:
            raise Broken(f"SET_LOOP 1 acknowledged; telemetry says loop {mode}")
        return "SET_LOOP refused while enabled and for mode 2 (NAK 3); taken while disabled, and telemetry said so"


def _v2_words(reason: int) -> str:
    """What a NAK 1 for a v3 command means: the device's highest version is v2, whose table has no such type."""
    return " (a device whose highest version is v2: not in its table)" if reason == p.NAK_UNKNOWN_TYPE else ""
