"""A device's counters believed only as far as they can be true: modular counters with a plausibility bound.

A plate driver's telemetry carries u32 counters (faults by kind, frames, setpoints lost, late, overrun ...) that
the host turns into the run's counts by their increments. A counter wraps at 2**32, so an increment is taken
modulo 2**32; but a counter that went *backwards* (a decrease that is no restart of the device) taken modulo
2**32 is a step of some four billion, and a run once reported "639926640000 × buffer overrun" and exited 0. So:

* an increment is believed up to :data:`STEP_MAX` per telemetry frame (a plate sends one every 20 ms; no
  counter of the protocol can honestly climb a million in that time), a wrap included (``0xFFFFFFF0`` to
  ``0x10`` is 32);
* a restart (the device's ``frames_ok`` fell) is believed only if its new ``frames_ok`` is no more than the
  frames the host sent since the last telemetry (:func:`plausible_restart`); its counts then start from zero,
  each within the bound;
* anything else is not believed (counted as nothing) and is itself a device fault, said and counted once per
  counter (:class:`CounterCheck`).

Examples
--------
>>> check = CounterCheck()
>>> check.steps(("overrun",), now=(3,), before=(5,), restarted=False)  # went backwards: no count, a fault
[0]
>>> print(check.words())  # doctest: +NORMALIZE_WHITESPACE
the plate reported counters that cannot be true (overrun went from 5 to 3, not a wrap or a restart;
1 such value in all): they were not counted
"""

from __future__ import annotations

import threading

WRAP = 1 << 32
STEP_MAX = 1 << 20  # the largest increment of one counter between two telemetry frames that is believed
RESTART_SLACK = 64  # frames a restarted device may count beyond what the host sent since the last telemetry


def plausible_restart(frames_ok: int, frames_sent_since: int) -> bool:
    """Whether a device whose ``frames_ok`` fell may have restarted: it cannot have taken more frames since than
    were sent (``frames_sent_since``, the host's count since the last telemetry, plus a little slack)."""
    return 0 <= frames_ok <= frames_sent_since + RESTART_SLACK


class CounterCheck:
    """The increments of a device's counters that can be true, and those that cannot (each counter's first said).

    Thread-safe: telemetry is taken on the reader thread, the report read on others."""

    def __init__(self, step_max: int = STEP_MAX):
        self.step_max = step_max
        self._lock = threading.Lock()
        self.implausible: dict[str, tuple[int, int, float | None]] = {}  # name: (before, now, when) of its first
        self.count = 0  # implausible values seen in all (each counter's said once)

    def steps(self, names, now, before, restarted: bool, at_s: float | None = None) -> list[int]:
        """The believed increment of each counter ``names[i]`` from ``before[i]`` to ``now[i]`` (a restart: from 0).

        Parameters
        ----------
        names : sequence of str
            The counters' names, for the words.
        now, before : sequence of int
            Their values in this telemetry and the one before (u32).
        restarted : bool
            The device restarted in between (checked with :func:`plausible_restart`).
        at_s : float, optional
            When (s into the run), for the words.

        Returns
        -------
        list of int
            Each increment, 0 where it cannot be true.
        """
        believed = []
        for name, value, last in zip(names, now, before, strict=True):
            value, last = int(value), int(last)
            step = value if restarted else (value - last) % WRAP
            if 0 <= value < WRAP and step <= self.step_max:
                believed.append(step)
                continue
            believed.append(0)
            with self._lock:
                self.count += 1
                self.implausible.setdefault(name, (last, value, at_s))
        return believed

    def words(self) -> str | None:
        """One sentence for the run's report, or None if every counter was believable."""
        with self._lock:
            if not self.implausible:
                return None
            said = "; ".join(f"{name} went from {last} to {now}" for name, (last, now, _) in
                             list(self.implausible.items())[:4])
            more = len(self.implausible) - 4
        plural = "s" if self.count != 1 else ""
        return (f"the plate reported counters that cannot be true ({said}{f'; {more} more' if more > 0 else ''}, "
                f"not a wrap or a restart; {self.count} such value{plural} in all): they were not counted")

    def first_s(self) -> float:
        """When the first implausible value came (s into the run; 0 if unknown)."""
        with self._lock:
            times = [at for _, _, at in self.implausible.values() if at is not None]
        return min(times, default=0.0)
