"""What a run on a plate driver came to, in words with times, and the exit status it earns.

A run whose plate was lost, cut its output or faulted must not pass for a clean one: the serial driver
(:mod:`ultraglide.devices.serial.plate`) keeps what happened and when, and words it as a :class:`RunReport`, and every
command that drives a plate (``play``, ``latency``, ``plate sweep``, the demo's status line) prints its
lines and exits with its status:

==== =====================================================================================
 0    clean: nothing below happened
 3    the plate faulted: its watchdog fired, it refused frames (NAK), its measured amplitude
      went over its limit, it reported values that cannot be (devices/protocol/ranges.py, counters),
      or its measured amplitude did not follow what it was sent (devices/serial/follow.py)
 4    the plate was lost: the port failed or vanished, the plate fell silent (no telemetry for
      500 ms), or the stream to it stopped (the writer failed)
 5    the plate cut its output: over-amplitude trip or overheat
 7    the engine was lost: the process that drives the device (``render.engine``) died or froze;
      the app made the device safe itself (ENABLE 0 on a serial plate) and says how
==== =====================================================================================

(6 is ``plate check``'s: a rule of the protocol failed.)

When several happened the largest status wins (a cut outranks a loss, a loss a fault). Underruns,
overruns, damaged frames, telemetry gaps and host stalls are said in words and leave the status alone:
they degrade a run without invalidating it.

Examples
--------
>>> lost = Incident(1.02, "lost", "plate disconnected at 1.02 s, back at 1.53 s; 6120 setpoints not sent")
>>> report = RunReport.of([lost], ["device faults: none"])
>>> report.exit_status, report.verdict
(4, 'the plate was lost (exit status 4)')
"""

from __future__ import annotations

from dataclasses import dataclass

EXIT_CLEAN = 0
EXIT_FAULTED = 3
EXIT_LOST = 4
EXIT_CUT = 5
EXIT_ENGINE_LOST = 7
SEVERITY = {"faulted": EXIT_FAULTED, "lost": EXIT_LOST, "cut": EXIT_CUT, "note": EXIT_CLEAN,
            "engine lost": EXIT_ENGINE_LOST}
VERDICTS = {EXIT_CLEAN: "clean", EXIT_FAULTED: "the plate faulted", EXIT_LOST: "the plate was lost",
            EXIT_CUT: "the plate cut its output", EXIT_ENGINE_LOST: "the engine was lost"}
MAX_LINES = 40  # the status crosses processes as JSON of at most 16 KB: longer reports are cut, and say so


@dataclass(frozen=True)
class Incident:
    """One thing that happened: when (s since the run started), its class (``faulted``, ``lost``, ``cut``
    or ``note``), and a sentence for people."""

    t_s: float
    kind: str
    words: str

    @property
    def exit_status(self) -> int:
        return SEVERITY[self.kind]

    def as_dict(self) -> dict:
        return {"t_s": round(self.t_s, 3), "kind": self.kind, "words": self.words}


@dataclass(frozen=True)
class RunReport:
    """The run's account: its exit status and the lines that say why (``lines``, each a sentence)."""

    exit_status: int
    lines: tuple[str, ...]

    @classmethod
    def of(cls, incidents, summary_lines=()) -> RunReport:
        """The incidents' sentences in time order, then ``summary_lines``; the status the worst incident earns."""
        ordered = sorted(incidents, key=lambda incident: incident.t_s)
        lines = [incident.words for incident in ordered] + list(summary_lines)
        if len(lines) > MAX_LINES:
            lines = lines[:MAX_LINES - 1] + [f"and {len(lines) - MAX_LINES + 1} more lines not shown"]
        return cls(max((incident.exit_status for incident in ordered), default=EXIT_CLEAN), tuple(lines))

    @property
    def verdict(self) -> str:
        """One line: clean, or what happened and the exit status it earns."""
        words = VERDICTS[self.exit_status]
        return words if self.exit_status == EXIT_CLEAN else f"{words} (exit status {self.exit_status})"

    def with_lines(self, lines, exit_status: int) -> RunReport:
        """This report after ``lines`` (what happened that this report's device could not see: its driver's
        process lost), with the larger of the two statuses."""
        return RunReport(max(self.exit_status, exit_status), (*lines, *self.lines))

    def as_dict(self) -> dict:
        return {"exit_status": self.exit_status, "verdict": self.verdict, "lines": list(self.lines)}

    @classmethod
    def from_dict(cls, data: dict | None) -> RunReport:
        """The report a device status carries (``status()["report"]``, e.g. read back from the engine's shared
        status); a device without one (audio, WAV, null) reports a clean run."""
        if not isinstance(data, dict):
            return cls(EXIT_CLEAN, ())
        return cls(int(data.get("exit_status", EXIT_CLEAN)), tuple(str(line) for line in data.get("lines", ())))


def seconds(t_s: float) -> str:
    """A time in a run, as people read it: ``1.02 s``."""
    return f"{t_s:.2f} s"


def times(count: int, noun: str = "time") -> str:
    """``1 time``, ``3 times``."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"
