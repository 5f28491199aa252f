"""The on-plate calibration's plan: which amplitude the plate plays when, at which press.

At each asked force (lighter, medium, heavier) the participant first slides for ``lead_s`` at a steady press,
then the plate steps through the amplitudes, each held ``step_s``, with a step at zero amplitude between
every two (friction at rest drifts as the skin's moisture changes: each reduced step is measured against the
zero steps beside it). A second pass goes through the amplitudes in reverse order, so that a slow drift
does not lean the curve one way. Of each step only the part after ``settle_s`` is measured (the plate, the
force sensors and the press settle first).

Times are seconds from the start of the stream; :meth:`CalibrationPlan.amplitude_at` gives the plate's
amplitude at any time (µm p-p), :meth:`CalibrationPlan.step_at` which step a time falls in.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

LEVELS = 8


@dataclass(frozen=True)
class Step:
    """One held amplitude: its start (s), length (s), amplitude (µm p-p) and the force level it belongs to."""

    start_s: float
    duration_s: float
    amplitude_um_pp: float
    level: int

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


@dataclass(frozen=True)
class CalibrationPlan:
    """See the module docstring. ``forces_n``: the presses asked for, in order; ``limit_um_pp``: the plate's
    limit (the largest amplitude stepped to is 95 % of it)."""

    forces_n: tuple[float, ...] = (0.25, 0.5, 0.9)
    limit_um_pp: float = 6.0
    levels: int = LEVELS
    step_s: float = 0.3
    settle_s: float = 0.12
    lead_s: float = 1.5
    passes: int = 2

    def __post_init__(self) -> None:
        if not self.forces_n or any(not (0.05 <= f <= 10.0) for f in self.forces_n):
            raise ValueError("the calibration's forces must lie in 0.05..10 N")
        if not 2 <= self.levels <= 40 or not 1 <= self.passes <= 10:
            raise ValueError("the calibration needs 2 to 40 amplitudes and 1 to 10 passes")
        if not 0.0 <= self.settle_s < self.step_s:
            raise ValueError("each step must last longer than its settling")

    @property
    def amplitudes_um_pp(self) -> np.ndarray:
        """The amplitudes stepped to: from a twelfth of the top up to 95 % of the limit."""
        top = 0.95 * self.limit_um_pp
        return np.linspace(top / 12.0, top, self.levels)

    def steps(self) -> list[Step]:
        return list(self._steps)

    @functools.cached_property
    def _steps(self) -> tuple[Step, ...]:  # the plan is frozen: its steps are worked out once (a source asks each ms)
        found = []
        t = 0.0
        amplitudes = self.amplitudes_um_pp.tolist()
        for level in range(len(self.forces_n)):
            found.append(Step(t, self.lead_s, 0.0, level))  # sliding in, at rest: the press settles
            t += self.lead_s
            for number in range(self.passes):
                order = amplitudes if number % 2 == 0 else amplitudes[::-1]
                for amplitude in order:
                    for value in (0.0, amplitude):
                        found.append(Step(t, self.step_s, value, level))
                        t += self.step_s
            found.append(Step(t, self.step_s, 0.0, level))  # the last reduced step's zero after it
            t += self.step_s
        return tuple(found)

    @functools.cached_property
    def _timeline(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The steps' starts (s), their amplitudes with a 0 after the last (µm p-p), and the plan's end (s)."""
        steps = self._steps
        return (np.array([s.start_s for s in steps]), np.array([s.amplitude_um_pp for s in steps] + [0.0]),
                steps[-1].end_s)

    @property
    def duration_s(self) -> float:
        return self._timeline[2]

    def level_starts_s(self) -> list[float]:
        """When each force level begins (s)."""
        starts = []
        for step in self.steps():
            if not starts or step.level != len(starts) - 1:
                starts.append(step.start_s)
        return starts

    def amplitude_at(self, t_s) -> np.ndarray:
        """The planned amplitude at times ``t_s`` (µm p-p; 0 before and after the plan)."""
        starts, values, end_s = self._timeline
        t = np.asarray(t_s, dtype=float)
        index = np.searchsorted(starts, t, side="right") - 1
        index = np.where((t < 0) | (t >= end_s), len(starts), index)
        return values[index]

    def step_at(self, t_s: float) -> int | None:
        """The index of the step that time ``t_s`` falls in, if it is in a step's measured part."""
        steps = self._steps
        index = int(np.searchsorted(self._timeline[0], t_s, side="right")) - 1
        if index < 0 or t_s >= steps[index].end_s:
            return None
        step = steps[index]
        settle = self.settle_s if step.duration_s == self.step_s else step.duration_s - (self.step_s - self.settle_s)
        return index if t_s >= step.start_s + settle else None

    def force_points(self, ramp_s: float = 0.3) -> tuple[list[float], list[float]]:
        """The asked force over time, for a simulated participant: each level's force from its start, reached over
        ``ramp_s`` (times s, forces N)."""
        times, forces = [], []
        for level, start in enumerate(self.level_starts_s()):
            force = self.forces_n[level]
            if times:
                times.append(start)
                forces.append(forces[-1])
            else:
                times.append(0.0)
                forces.append(force)
                continue
            times.append(start + ramp_s)
            forces.append(force)
        times.append(self.duration_s + 1.0)
        forces.append(forces[-1])
        return times, forces

    def words(self) -> str:
        return (f"{len(self.forces_n)} presses ({', '.join(f'{f:g}' for f in self.forces_n)} N), {self.levels} "
                f"amplitudes up to {self.amplitudes_um_pp[-1]:.2g} µm p-p, {self.passes} passes, "
                f"{math.ceil(self.duration_s)} s")
