"""What the plate driver keeps of a run and tells of it: :class:`RunAccount` records what happened and when
(from every thread, under one lock held for a copy), and words it as a
:class:`~ultraglide.devices.serial.run_report.RunReport` with the exit status it earns."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from ultraglide.devices import protocol as p
from ultraglide.devices.counter_check import CounterCheck
from ultraglide.devices.protocol.ranges import FieldCheck
from ultraglide.devices.serial.follow import AmplitudeFollow, CarrierFollow
from ultraglide.devices.serial.link import COMMAND_NAMES, CUT_FAULTS, CUT_WORDS, MAX_OUTAGES, Outage, Pacing
from ultraglide.devices.serial.run_report import Incident, RunReport, seconds, times

SEVERITY = {"watchdog": "faulted", "over-limit": "faulted", "bad-command": "faulted", "trip": "cut",
            "overheat": "cut"}


@dataclass(frozen=True)
class RunFigures:
    """What the report words besides the account: counts and state the other parts keep."""

    counters: object  # SerialCounters
    faults: dict[str, int]
    link_run: dict[str, int]
    pacing: Pacing
    depth_worst: float  # values
    rest_failure: str | None


class RunAccount:
    """What happened over a run and when (s since :meth:`restart`), written by any thread."""

    def __init__(self, lock: threading.Lock):
        self._lock = lock
        self.restart()

    def restart(self) -> None:
        self.started = time.perf_counter()
        self._outages: list[Outage] = []
        self._outages_dropped = 0
        self._refusals: dict[tuple[str, str], list] = {}  # (command, reason) → [count, first s]
        self._fault_first_s: dict[str, float] = {}
        self._cut_at: tuple[float, str] | None = None
        self._stall_longest = (0.0, 0.0)  # (duration s, at s)
        self._late_longest = (0.0, 0.0)  # the longest gap between frames while streaming, over the buffer (s, at s)
        self._bad_received = [0, 0, None]  # crc, malformed, first s
        self._writer_failure: tuple[float, str] | None = None
        self._restarts: list[tuple[float, str]] = []  # (s, why) of the board's own restarts mid-run (a few kept)
        self._restarts_count = 0
        self.reenabled_first_s = 0.0
        self.rested = False

    @property
    def counter_check(self) -> CounterCheck:
        """The plausibility of the device's u32 counters over the run (devices/counter_check.py)."""
        check = getattr(self, "_counter_check", None)
        if check is None:
            check = self._counter_check = CounterCheck()
        return check

    @property
    def field_check(self) -> FieldCheck:
        """The device's values that could not be believed over the run (devices/protocol/ranges.py)."""
        check = getattr(self, "_field_check", None)
        if check is None:
            check = self._field_check = FieldCheck()
        return check

    @property
    def follow(self) -> AmplitudeFollow:
        """Whether the plate's measured amplitude follows what it is sent, over the run (devices/serial/follow.py)."""
        follow = getattr(self, "_follow", None)
        if follow is None:
            follow = self._follow = AmplitudeFollow()
        return follow

    @property
    def carrier_follow(self) -> CarrierFollow:
        """Whether the carrier the plate reports is the one it was sent, over the run (devices/serial/follow.py)."""
        follow = getattr(self, "_carrier_follow", None)
        if follow is None:
            follow = self._carrier_follow = CarrierFollow()
        return follow

    def now_s(self) -> float:
        """Seconds since the run started."""
        return time.perf_counter() - self.started

    def rest_once(self) -> bool:
        """True the first time only: the end of the run rests the plate exactly once."""
        with self._lock:
            first, self.rested = not self.rested, True
        return first

    # ---- what happened --------------------------------------------------------------------------
    def outage(self, cause: str, discarded: int) -> None:
        with self._lock:
            if len(self._outages) < MAX_OUTAGES:
                self._outages.append(Outage(self.now_s(), cause, discarded))
            else:
                self._outages_dropped += 1

    def back(self, discarded: int) -> None:
        with self._lock:
            if self._outages and self._outages[-1].back_s is None:
                outage = self._outages[-1]
                outage.back_s = self.now_s()
                outage.not_sent = discarded - outage.discarded_before

    def retry_failed(self, error: str) -> None:
        with self._lock:
            if self._outages and self._outages[-1].back_s is None:
                self._outages[-1].last_error = error.split("; ")[0]  # without the advice

    def refused(self, kind: int, reason: int) -> None:
        """A NAK, counted by what it refused and why."""
        command = COMMAND_NAMES.get(kind, f"command {kind:#04x}")
        words = p.NAK_REASONS.get(reason, f"reason {reason}")
        with self._lock:
            entry = self._refusals.setdefault((command, words), [0, self.now_s()])
            entry[0] += 1

    def board_restarted(self, why: str) -> None:
        """The plate driver came back from a loss of the link having restarted itself (its watchdog, a fault), as
        its new handshake says (``why``, in words)."""
        with self._lock:
            self._restarts_count += 1
            if len(self._restarts) < MAX_OUTAGES:
                self._restarts.append((self.now_s(), why))

    def bad_frames(self, crc_errors: int, framing_errors: int) -> None:
        with self._lock:
            if self._bad_received[2] is None:
                self._bad_received[2] = self.now_s()
            self._bad_received[0], self._bad_received[1] = crc_errors, framing_errors

    def faults_seen(self, bits: int) -> None:
        """Faults newly counted: the first time of each, and the cut (trip, overheat) that ends streaming."""
        now = self.now_s()
        with self._lock:
            for bit, name in p.FAULT_NAMES.items():
                if bits & bit:
                    self._fault_first_s.setdefault(name, now)
            for bit in CUT_FAULTS:
                if bits & bit and self._cut_at is None:
                    self._cut_at = (now, p.FAULT_NAMES[bit])

    def host_stalled(self, stalled_s: float, at: float) -> None:
        with self._lock:
            if stalled_s > self._stall_longest[0]:
                self._stall_longest = (stalled_s, at - self.started)

    def late_frame(self, gap_s: float) -> None:
        with self._lock:
            self._late_longest = max(self._late_longest, (gap_s, self.now_s()))

    def writer_failed(self, words: str) -> None:
        with self._lock:
            self._writer_failure = (self.now_s(), words)

    # ---- in words -------------------------------------------------------------------------------
    def report(self, figures: RunFigures) -> RunReport:
        """The run so far in words, with the exit status it earns (see :mod:`.run_report`)."""
        with self._lock:
            outages = [(o.lost_s, o.cause, o.back_s, o.not_sent, o.last_error, o.discarded_before)
                       for o in self._outages]
            refusals = {key: tuple(value) for key, value in self._refusals.items()}
            first = dict(self._fault_first_s)
            cut_at, stall, bad = self._cut_at, self._stall_longest, list(self._bad_received)
            late = self._late_longest
            writer_failure, dropped = self._writer_failure, self._outages_dropped
            restarts, restarts_count = list(self._restarts), self._restarts_count
        counters = figures.counters
        incidents = []
        for at_s, why in restarts:  # a device fault: the board reset itself under the run
            incidents.append(Incident(at_s, "faulted", f"the plate driver restarted itself, its handshake at "
                                                       f"{seconds(at_s)} said: {why}"))
        if restarts_count > len(restarts):
            incidents.append(Incident(restarts[-1][0], "faulted",
                                      f"and {restarts_count - len(restarts)} more restarts of the plate driver"))
        for lost_s, cause, back_s, not_sent, last_error, before in outages:
            if back_s is None:
                not_sent = counters.setpoints_discarded - before
                last = f" (the last try: {last_error})" if last_error else ""
                words = (f"plate lost at {seconds(lost_s)}: {cause}; not back by the end{last}; "
                         f"{not_sent} setpoints not sent")
            else:
                words = (f"plate lost at {seconds(lost_s)}: {cause}; back at {seconds(back_s)}; "
                         f"{not_sent} setpoints not sent")
            incidents.append(Incident(lost_s, "lost", words))
        if dropped:
            incidents.append(Incident(outages[-1][0], "lost", f"and {dropped} more losses of the plate"))
        if writer_failure is not None:
            incidents.append(Incident(writer_failure[0], "lost", f"the stream to the plate stopped at "
                                      f"{seconds(writer_failure[0])}: {writer_failure[1]}"))
        if cut_at is not None:
            incidents.append(Incident(cut_at[0], "cut", f"the plate cut its output at {seconds(cut_at[0])} "
                                      f"({CUT_WORDS.get(cut_at[1], cut_at[1])}): streaming stopped there; the host "
                                      "does not enable it again, so it stays off until the next run"))
        for name, count in figures.faults.items():
            if not count or cut_at is not None and name == cut_at[1] and count == 1:
                continue  # (the cut says it)
            at = first.get(name, 0.0)
            incidents.append(Incident(at, SEVERITY.get(name, "note"), f"the plate raised {name} {times(count)} "
                                      f"(first at {seconds(at)}): {p.FAULT_WORDS.get(name, name)}"))
        for (command, reason), (count, at) in refusals.items():
            incidents.append(Incident(at, "faulted", f"the plate refused {times(count, 'frame')} of {command} "
                                                     f"({reason}), first at {seconds(at)}"
                                      + ("; its latched faults were not cleared again" if command == "CLEAR_FAULTS"
                                         else "")))
        implausible = self.counter_check.words()
        if implausible is not None:  # a device fault: its numbers are not to be believed
            incidents.append(Incident(self.counter_check.first_s(), "faulted", implausible))
        impossible = self.field_check.words()
        if impossible is not None:  # a device fault: those frames were not taken
            incidents.append(Incident(self.field_check.first_s(), "faulted", impossible))
        unfollowed = self.follow.words()
        if unfollowed is not None:  # a device fault: it does not play what it is sent
            incidents.append(Incident(self.follow.first_s(), "faulted", unfollowed))
        off_carrier = self.carrier_follow.words()
        if off_carrier is not None:  # a device fault: it plays a carrier it was not sent
            incidents.append(Incident(self.carrier_follow.first_s(), "faulted", off_carrier))
        if bad[0] or bad[1]:
            incidents.append(Incident(bad[2] or 0.0, "note", f"{times(bad[0] + bad[1], 'frame')} from the plate "
                                      f"arrived damaged ({bad[0]} with a bad CRC, {bad[1]} truncated or malformed), "
                                      f"first at {seconds(bad[2] or 0.0)}"))
        incidents += self._timing_incidents(figures, stall, late)
        return RunReport.of(incidents, self._summary(figures))

    def _timing_incidents(self, figures: RunFigures, stall: tuple, late: tuple) -> list[Incident]:
        counters, pacing = figures.counters, figures.pacing
        incidents = []
        if stall[0]:
            skipped = counters.setpoints_skipped
            incidents.append(Incident(stall[1], "note", f"the host stalled {times(counters.host_stalls)} "
                                      f"(longest {stall[0]:.2f} s at {seconds(stall[1])})"
                                      + (f"; {skipped} setpoints skipped so the latency stays at the plate's "
                                         f"{1000 * pacing.lead / pacing.rate_hz:.0f} ms buffer" if skipped else "")))
        if late[0]:
            lasts_ms = 1000 * pacing.buffer_lasts_s
            incidents.append(Incident(late[1], "note", f"the host sent {times(counters.late_frames, 'frame')} "
                                      f"later than the plate's {lasts_ms:.0f} ms buffer lasts (the longest gap "
                                      f"{1000 * late[0]:.0f} ms, at {seconds(late[1])}): the plate may have run dry"))
        if counters.reenables:
            incidents.append(Incident(self.reenabled_first_s, "note",
                                      f"the plate was off while the host streamed to it "
                                      f"{times(counters.reenables)} (an ENABLE lost on the link?), first at "
                                      f"{seconds(self.reenabled_first_s)}: enabled again"))
        return incidents

    def _summary(self, figures: RunFigures) -> list[str]:
        counters, run = figures.counters, figures.link_run
        lines = []
        damaged = run["crc_errors"] + run["framing_errors"]
        if damaged:
            lines.append(f"the plate received {times(damaged, 'damaged frame')} ({run['crc_errors']} with a bad CRC, "
                         f"{run['framing_errors']} malformed)")
        lost, late, overrun = run["lost_setpoints"], run["late_setpoints"], run["overrun_setpoints"]
        if lost or late or overrun:
            parts = [f"{lost} lost" + (f" ({counters.setpoints_skipped} of them skipped by the host)"
                                       if counters.setpoints_skipped else "")]
            parts += [f"{late} late"] if late else []
            parts += [f"{overrun} dropped by overruns"] if overrun else []
            lines.append("the plate counted setpoints " + ", ".join(parts))
        if counters.depth_corrections:
            worst_ms = 1000 * figures.depth_worst / figures.pacing.rate_hz
            lines.append(f"the plate's buffer drifted from its depth {times(counters.depth_corrections)} (by "
                         f"up to {worst_ms:.0f} ms: its clock against the host's, or its playback started again "
                         "late); the host moved its lead to bring it back")
        if figures.rest_failure and self.rested:
            lines.append(f"the plate could not be rested at the end ({figures.rest_failure}): its watchdog rests "
                         "it if it is still powered and was enabled")
        return lines
