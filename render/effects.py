"""Temporal friction effects, evaluated and mixed with the texture's friction (the values: ``textures.effects``).

:func:`sample` evaluates an effect over a numpy time array (s since its trigger), vectorised::

    >>> import numpy as np
    >>> from ultraglide.textures.effects import ADSR, Sine
    >>> t = np.array([0.0, 0.005, 0.010])
    >>> np.round(sample(Sine(100.0, 0.4), t), 6).tolist()        # 0.4·(1 − cos 2π·100 t)/2
    [0.0, 0.4, 0.0]
    >>> np.round(sample(ADSR(0.01, 0.0, 0.0, 0.01, sustain_level=1.0), t), 6).tolist()
    [0.0, 0.5, 1.0]

:class:`EffectPlayer` is what the renderer runs each block: it finds the triggers in the finger's path
(compiled, sample-exact), starts and ends voices (a fixed pool), evaluates them into preallocated
buffers and subtracts their sum from the texture's ratio, clipping to [0, 1] and counting what went
above 1 (the model's inverse then clamps below its floor and counts it, as for textures). Nothing on
its block path allocates, except the rare named event (a deque entry, from the thread that reports it).
"""

from __future__ import annotations

import collections
import math

import numba
import numpy as np
from ultraglide.textures.effects import (
    ADSR,
    Binding,
    Constant,
    Effect,
    Product,
    Sawtooth,
    Sequence,
    Sine,
    Square,
    Sum,
    Triangle,
)

VOICES = 16  # effects playing at once; a new one beyond takes the oldest's place
LOG = 1024  # voice starts remembered (for tests and status)
TWO_PI = 2.0 * math.pi


# ---- compiled loops --------------------------------------------------------------------------------------
@numba.njit(cache=True, nogil=True)
def _adsr(t, attack, decay, sustain, release, peak, level, out):  # pragma: no cover - compiled
    held = peak * level
    t1 = attack
    t2 = t1 + decay
    t3 = t2 + sustain
    t4 = t3 + release
    for i in range(len(t)):
        s = t[i]
        if s < 0.0 or s >= t4:
            out[i] = 0.0
        elif s < t1:
            out[i] = peak * s / attack
        elif s < t2:
            out[i] = peak + (held - peak) * (s - t1) / decay
        elif s < t3:
            out[i] = held
        else:
            out[i] = held * (1.0 - (s - t3) / release)


@numba.njit(cache=True, nogil=True)
def _zone_edges(x, y, down, n, x0, y0, x1, y1, min_step, prev_inside, prev_x, prev_y, rises, falls):  # pragma: no cover
    """Where the finger (down, inside the box, moving at least ``min_step`` mm a sample) starts and stops
    being so. Returns (rises found, falls found, inside at the end)."""
    n_rise = 0
    n_fall = 0
    inside = prev_inside
    for i in range(n):
        step = math.hypot(x[i] - prev_x, y[i] - prev_y)
        prev_x = x[i]
        prev_y = y[i]
        now = down[i] and x0 <= x[i] < x1 and y0 <= y[i] < y1 and (min_step <= 0.0 or step >= min_step)
        if now and not inside:
            rises[n_rise] = i
            n_rise += 1
        elif inside and not now:
            falls[n_fall] = i
            n_fall += 1
        inside = now
    return n_rise, n_fall, inside


@numba.njit(cache=True, nogil=True)
def _crossings(along, across, down, n, lo, hi, lines, prev_cell, rises):  # pragma: no cover - compiled
    """Where the finger, down and within [lo, hi) across, moves from between one pair of lines to another.
    ``prev_cell`` −1: not yet placed. Returns (crossings found, cell at the end)."""
    count = 0
    cell = prev_cell
    for i in range(n):
        if not down[i] or not (lo <= across[i] < hi):
            cell = -1
            continue
        now = 0
        while now < len(lines) and lines[now] <= along[i]:
            now += 1
        if cell >= 0 and now != cell:
            rises[count] = i
            count += 1
        cell = now
    return count, cell


def warm_up() -> None:
    """Compile (or load from numba's cache) the loops, outside any real-time block."""
    t = np.zeros(2)
    _adsr(t, 0.1, 0.1, 0.1, 0.1, 1.0, 0.5, np.empty(2))
    flags = np.ones(2, dtype=np.bool_)
    idx = np.empty(2, dtype=np.int64)
    _zone_edges(t, t, flags, 2, -1.0, -1.0, 1.0, 1.0, 0.0, False, 0.0, 0.0, idx, idx)
    _crossings(t, t, flags, 2, -1.0, 1.0, np.array([0.5]), -1, idx)


# ---- evaluation plans: each node owns its scratch buffers --------------------------------------------------
class _Plan:
    def evaluate(self, t: np.ndarray, out: np.ndarray) -> None:
        raise NotImplementedError


class _Oscillator(_Plan):
    def __init__(self, effect, capacity: int):
        self.f, self.depth, self.kind = effect.frequency_hz, effect.depth, type(effect)
        self.flag = np.empty(capacity, dtype=np.bool_)

    def evaluate(self, t, out):
        n = len(t)
        if self.kind is Sine:  # depth (1 − cos 2πft) / 2
            np.multiply(t, TWO_PI * self.f, out=out)
            np.cos(out, out=out)
            np.multiply(out, -0.5 * self.depth, out=out)
            np.add(out, 0.5 * self.depth, out=out)
            return
        np.multiply(t, self.f, out=out)
        np.mod(out, 1.0, out=out)  # the phase in [0, 1)
        if self.kind is Square:
            flag = self.flag[:n]
            np.greater_equal(out, 0.5, out=flag)
            out.fill(0.0)
            np.copyto(out, self.depth, where=flag)
        elif self.kind is Sawtooth:
            np.multiply(out, self.depth, out=out)
        elif self.kind is Triangle:  # depth (1 − |1 − 2 phase|)
            np.multiply(out, -2.0, out=out)
            np.add(out, 1.0, out=out)
            np.abs(out, out=out)
            np.multiply(out, -self.depth, out=out)
            np.add(out, self.depth, out=out)


class _Constant(_Plan):
    def __init__(self, effect, capacity: int):
        self.level, self.length = effect.level, effect.length_s
        self.flag = np.empty(capacity, dtype=np.bool_)

    def evaluate(self, t, out):
        if math.isinf(self.length):
            out.fill(self.level)
            return
        flag = self.flag[:len(t)]
        np.less(t, self.length, out=flag)
        out.fill(0.0)
        np.copyto(out, self.level, where=flag)


class _ADSR(_Plan):
    def __init__(self, effect, capacity: int):
        self.args = (effect.attack_s, effect.decay_s, effect.sustain_s, effect.release_s, effect.peak,
                     effect.sustain_level)

    def evaluate(self, t, out):
        _adsr(t, *self.args, out)


class _Combine(_Plan):
    def __init__(self, children, capacity: int, ufunc):
        self.children = [plan(child, capacity) for child in children]
        self.scratch = np.empty(capacity)
        self.ufunc = ufunc

    def evaluate(self, t, out):
        self.children[0].evaluate(t, out)
        scratch = self.scratch[:len(t)]
        for child in self.children[1:]:
            child.evaluate(t, scratch)
            self.ufunc(out, scratch, out=out)


class _Sequence(_Plan):
    def __init__(self, effect, capacity: int):
        self.children = [plan(part, capacity) for part in effect.parts]
        starts = np.cumsum([0.0] + [part.duration_s for part in effect.parts[:-1]])
        self.spans = [(float(start), float(start + part.duration_s)) for start, part in zip(starts, effect.parts,
                                                                                           strict=True)]
        self.local, self.scratch = np.empty(capacity), np.empty(capacity)
        self.flag, self.flag2 = np.empty(capacity, dtype=np.bool_), np.empty(capacity, dtype=np.bool_)

    def evaluate(self, t, out):
        n = len(t)
        local, scratch, flag, flag2 = self.local[:n], self.scratch[:n], self.flag[:n], self.flag2[:n]
        out.fill(0.0)
        for child, (start, end) in zip(self.children, self.spans, strict=True):
            np.subtract(t, start, out=local)
            child.evaluate(local, scratch)
            np.less(t, start, out=flag)  # outside the part's span: nothing of it
            np.greater_equal(t, end, out=flag2)
            np.logical_or(flag, flag2, out=flag)
            np.copyto(scratch, 0.0, where=flag)
            np.add(out, scratch, out=out)


def plan(effect: Effect, capacity: int) -> _Plan:
    """An evaluator for ``effect`` over up to ``capacity`` times at once, with its buffers allocated now."""
    if isinstance(effect, Sine | Square | Sawtooth | Triangle):
        return _Oscillator(effect, capacity)
    if isinstance(effect, Constant):
        return _Constant(effect, capacity)
    if isinstance(effect, ADSR):
        return _ADSR(effect, capacity)
    if isinstance(effect, Sum):
        return _Combine(effect.terms, capacity, np.add)
    if isinstance(effect, Product):
        return _Combine(effect.factors, capacity, np.multiply)
    if isinstance(effect, Sequence):
        return _Sequence(effect, capacity)
    raise TypeError(f"not an effect: {effect!r}")


def sample(effect: Effect, t_s) -> np.ndarray:
    """The effect's value (drop in friction ratio) at times ``t_s`` (s since its trigger); 0 before 0 and
    after its duration."""
    t = np.ascontiguousarray(t_s, dtype=np.float64)
    out = np.empty(len(t))
    plan(effect, max(1, len(t))).evaluate(t, out)
    if math.isfinite(effect.duration_s):
        out[(t < 0) | (t >= effect.duration_s)] = 0.0
    else:
        out[t < 0] = 0.0
    return out


# ---- the player -------------------------------------------------------------------------------------------
class EffectPlayer:
    """Finds triggers in the finger's path, plays their effects and mixes them into the friction ratio.

    One thread calls :meth:`mix` (the block path); :meth:`trigger` may be called from any thread.
    ``starts`` gives (binding index, start time s) of the most recent voices, for tests and status;
    ``clipped_samples`` counts mixed ratios above 1 (more friction than the plate at rest), clipped to 1
    (ratios below the model's floor are clamped and counted by the inverse, as for textures)."""

    def __init__(self, bindings: tuple[Binding, ...], control_rate_hz: float, capacity: int = 4096):
        warm_up()
        self.bindings = tuple(bindings)
        self.control_rate_hz = float(control_rate_hz)
        self.capacity = capacity
        self.plans = [plan(b.effect, capacity) for b in self.bindings]
        self.durations = [b.effect.duration_s for b in self.bindings]
        self._events = collections.deque(maxlen=256)
        self._names = {}
        for k, b in enumerate(self.bindings):
            if b.trigger.on == "event":
                self._names.setdefault(b.trigger.name, []).append(k)
        self._inside = [False] * len(self.bindings)
        self._cell = [-1] * len(self.bindings)
        self._prev_xy = np.full(2, math.nan)  # the finger's last position in the previous block, mm
        self._lines = [np.asarray(b.trigger.lines_mm, dtype=np.float64) for b in self.bindings]
        self._rises = np.empty(capacity, dtype=np.int64)
        self._falls = np.empty(capacity, dtype=np.int64)
        self._down = np.empty(capacity, dtype=np.bool_)
        self._sum = np.empty(capacity)
        self._local = np.empty(capacity)
        self._value = np.empty(capacity)
        self._gain = np.empty(capacity)
        self._flag = np.empty(capacity, dtype=np.bool_)
        self._mixed = np.empty(capacity)
        # the voice pool: binding index (−1 free), start s, gate off s (inf while held)
        self.voice_binding = np.full(VOICES, -1, dtype=np.int64)
        self.voice_start = np.zeros(VOICES)
        self.voice_gate_off = np.full(VOICES, math.inf)
        self.started = 0
        self._log = np.zeros((LOG, 2))  # (binding, start s) of the latest voices, a ring
        self.clipped_samples = 0

    def trigger(self, name: str, t_s: float) -> bool:
        """An app's named event at ``t_s`` (perf_counter s; or the offline clock). False: no binding has it."""
        if name not in self._names:
            return False
        self._events.append((name, float(t_s)))
        return True

    # ---- voices -----------------------------------------------------------------------------------------
    def _start(self, binding: int, t_s: float, held: bool) -> None:
        slot = -1
        oldest = 0
        for v in range(VOICES):  # a loop over the pool, not over samples
            if self.voice_binding[v] < 0:
                slot = v
                break
            if self.voice_start[v] < self.voice_start[oldest]:
                oldest = v
        slot = oldest if slot < 0 else slot
        self.voice_binding[slot] = binding
        self.voice_start[slot] = t_s
        self.voice_gate_off[slot] = math.inf if held else -math.inf
        row = self._log[self.started % LOG]
        row[0] = binding
        row[1] = t_s
        self.started += 1

    def _release(self, binding: int, t_s: float) -> None:
        for v in range(VOICES):
            if self.voice_binding[v] == binding and self.voice_gate_off[v] == math.inf:
                self.voice_gate_off[v] = t_s

    def _find_triggers(self, times, x, y, down, n) -> None:
        prev_x, prev_y = float(self._prev_xy[0]), float(self._prev_xy[1])
        if math.isnan(prev_x):
            prev_x, prev_y = float(x[0]), float(y[0])
        for k, b in enumerate(self.bindings):
            trig = b.trigger
            on = trig.on
            if on == "event":
                continue
            region = trig.region_mm
            if region is None:
                x0 = y0 = -math.inf
                x1 = y1 = math.inf
            else:
                x0, y0, x1, y1 = region[0], region[1], region[0] + region[2], region[1] + region[3]
            if on == "cross":
                along, across = (x, y) if trig.axis == "x" else (y, x)
                lo, hi = (y0, y1) if trig.axis == "x" else (x0, x1)
                count, self._cell[k] = _crossings(along, across, down, n, lo, hi, self._lines[k], self._cell[k],
                                                  self._rises)
                for j in range(count):
                    self._start(k, float(times[self._rises[j]]), False)
                continue
            min_step = trig.min_speed_mm_s / self.control_rate_hz
            n_rise, n_fall, self._inside[k] = _zone_edges(x, y, down, n, x0, y0, x1, y1, min_step, self._inside[k],
                                                          prev_x, prev_y, self._rises, self._falls)
            if on == "start":
                for j in range(n_rise):
                    self._start(k, float(times[self._rises[j]]), False)
            elif on == "end":
                for j in range(n_fall):
                    self._start(k, float(times[self._falls[j]]), False)
            else:  # while: each rise starts a held voice, each fall releases it (in time order)
                j_rise = j_fall = 0
                while j_rise < n_rise or j_fall < n_fall:
                    if j_fall >= n_fall or (j_rise < n_rise and self._rises[j_rise] < self._falls[j_fall]):
                        self._start(k, float(times[self._rises[j_rise]]), True)
                        j_rise += 1
                    else:
                        self._release(k, float(times[self._falls[j_fall]]))
                        j_fall += 1
        self._prev_xy[0] = x[n - 1]
        self._prev_xy[1] = y[n - 1]

    # ---- the block path ----------------------------------------------------------------------------------
    def mix(self, times, x, y, down, ratio) -> np.ndarray:
        """The texture's ``ratio`` with the effects playing at ``times`` (s) subtracted, clipped to [0, 1]. The
        array returned is a buffer of the player's, overwritten by the next block (a copy if n > capacity)."""
        n = len(times)
        if n > self.capacity:  # a long catch-up block: in pieces
            out = np.empty(n)
            for start in range(0, n, self.capacity):
                end = min(n, start + self.capacity)
                piece_down = down if np.ndim(down) == 0 else down[start:end]
                out[start:end] = self.mix(times[start:end], x[start:end], y[start:end], piece_down,
                                          ratio[start:end])
            return out
        if n == 0:
            return ratio
        flags = self._down[:n]
        flags[:] = down
        while self._events:
            name, t_s = self._events.popleft()
            for k in self._names.get(name, ()):
                self._start(k, max(t_s, float(times[0])), False)
        self._find_triggers(times, x, y, flags, n)
        total = self._sum[:n]
        total.fill(0.0)
        local, value, gain, flag = self._local[:n], self._value[:n], self._gain[:n], self._flag[:n]
        last = float(times[n - 1])
        for v in range(VOICES):
            k = int(self.voice_binding[v])
            if k < 0:
                continue
            start, gate_off = float(self.voice_start[v]), float(self.voice_gate_off[v])
            np.subtract(times, start, out=local)
            self.plans[k].evaluate(local, value)
            np.less(local, 0.0, out=flag)  # before the start: nothing (masks, not products: no casts, no buffers)
            np.copyto(value, 0.0, where=flag)
            if gate_off == -math.inf:  # once: for its duration
                duration = self.durations[k]
                np.greater_equal(local, duration, out=flag)
                np.copyto(value, 0.0, where=flag)
                if last - start >= duration:
                    self.voice_binding[v] = -1
            else:  # held: full until the gate is off, then a linear release
                release = self.bindings[k].release_s
                if gate_off != math.inf:
                    np.subtract(times, gate_off, out=gain)
                    if release > 0:
                        np.multiply(gain, -1.0 / release, out=gain)
                        np.add(gain, 1.0, out=gain)
                        np.clip(gain, 0.0, 1.0, out=gain)
                    else:
                        np.greater_equal(gain, 0.0, out=flag)
                        gain.fill(1.0)
                        np.copyto(gain, 0.0, where=flag)
                    np.multiply(value, gain, out=value)
                    if last >= gate_off + release:
                        self.voice_binding[v] = -1
            np.add(total, value, out=total)
        mixed = self._mixed[:n]
        np.subtract(ratio, total, out=mixed)
        np.greater(mixed, 1.0, out=flag)
        self.clipped_samples += int(np.count_nonzero(flag))  # above rest; below the model's floor is counted there
        np.clip(mixed, 0.0, 1.0, out=mixed)
        return mixed

    @property
    def starts(self) -> list[tuple[int, float]]:
        """(binding index, start time s) of the latest voices (up to 1024), oldest first."""
        first = max(0, self.started - LOG)
        return [(int(self._log[k % LOG, 0]), float(self._log[k % LOG, 1])) for k in range(first, self.started)]

    @property
    def playing(self) -> int:
        """Voices playing now."""
        return int(np.count_nonzero(self.voice_binding >= 0))
