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
    ON,
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
EVENTS = 1024  # events found in one block at most (a catch-up block of a wild path may drop some)
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


ON_START, ON_END, ON_WHILE, ON_CROSS, ON_EVENT = range(5)  # a trigger's kind, as the kernel knows it
PLAY_ONCE, PLAY_HELD, RELEASE = range(3)  # what an event found in the path does


@numba.njit(cache=True, nogil=True)
def _find_events(x, y, down, n, previous, kinds, boxes, min_steps, across_y, lines, line_counts, state,
                 event_binding, event_index, event_action):  # pragma: no cover - compiled
    """Every binding's events in one block, in sample order per binding; returns how many (at most the
    event arrays' length). ``previous``: the finger's last (x, y) before the block, updated; ``state``:
    per binding, 1/0 inside its zone (start, end, while) or the cell between its lines (cross, −1: not yet
    placed), updated. A zone is down, inside the box and moving at ``min_steps`` mm a sample or more."""
    count = 0
    room = len(event_binding)
    for k in range(len(kinds)):
        kind = kinds[k]
        if kind == ON_EVENT:
            continue
        x0, y0, x1, y1 = boxes[k, 0], boxes[k, 1], boxes[k, 2], boxes[k, 3]
        prev_x, prev_y = previous[0], previous[1]
        current = state[k]
        for i in range(n):
            inside = down[i] and x0 <= x[i] < x1 and y0 <= y[i] < y1
            if kind == ON_CROSS:
                now = -1
                if inside:
                    along = y[i] if across_y[k] else x[i]
                    now = 0
                    while now < line_counts[k] and lines[k, now] <= along:
                        now += 1
                    if current >= 0 and now != current and count < room:
                        event_binding[count], event_index[count], event_action[count] = k, i, PLAY_ONCE
                        count += 1
                current = now
                continue
            if inside and min_steps[k] > 0.0:
                inside = math.hypot(x[i] - prev_x, y[i] - prev_y) >= min_steps[k]
            prev_x, prev_y = x[i], y[i]
            now = 1 if inside else 0
            if now != current and count < room:
                action = -1
                if kind == ON_START and now == 1:
                    action = PLAY_ONCE
                elif kind == ON_END and now == 0:
                    action = PLAY_ONCE
                elif kind == ON_WHILE:
                    action = PLAY_HELD if now == 1 else RELEASE
                if action >= 0:
                    event_binding[count], event_index[count], event_action[count] = k, i, action
                    count += 1
            current = now
        state[k] = current
    if n:
        previous[0], previous[1] = x[n - 1], y[n - 1]
    return count


@numba.njit(cache=True, nogil=True)
def _oscillate(t, kind, frequency, depth, out):  # pragma: no cover - compiled
    """kind 0 sine, 1 square, 2 sawtooth, 3 triangle; each from 0 at phase 0, swinging to ``depth``."""
    for i in range(len(t)):
        phase = t[i] * frequency
        phase -= math.floor(phase)
        if kind == 0:
            out[i] = 0.5 * depth * (1.0 - math.cos(TWO_PI * phase))
        elif kind == 1:
            out[i] = depth if phase >= 0.5 else 0.0
        elif kind == 2:
            out[i] = depth * phase
        else:
            out[i] = depth * (1.0 - abs(1.0 - 2.0 * phase))


@numba.njit(cache=True, nogil=True)
def _accumulate(times, start, duration, gate_off, release, value, total):  # pragma: no cover - compiled
    """Add one voice's ``value`` (evaluated at times − start) into ``total``: nothing before its start or after
    its duration; a held voice whose gate went off at ``gate_off`` fades linearly over ``release`` s."""
    released = -math.inf < gate_off < math.inf
    for i in range(len(times)):
        s = times[i] - start
        if s < 0.0 or s >= duration:
            continue
        gain = 1.0
        if released and times[i] >= gate_off:
            gain = 1.0 - (times[i] - gate_off) / release if release > 0.0 else 0.0
            if gain <= 0.0:
                continue
        total[i] += gain * value[i]


@numba.njit(cache=True, nogil=True)
def _subtract_clipped(ratio, total, out):  # pragma: no cover - compiled
    """out = ratio − total within [0, 1]; returns how many were above 1."""
    above = 0
    for i in range(len(out)):
        r = ratio[i] - total[i]
        if r > 1.0:
            above += 1
            r = 1.0
        elif r < 0.0:
            r = 0.0
        out[i] = r
    return above


@numba.njit(cache=True, nogil=True)
def _subtract_below(command, total, down, floor):  # pragma: no cover - compiled
    """command −= total within [0, 1], in place; returns how many fell below ``floor`` where ``down``."""
    below = 0
    for i in range(len(command)):
        r = command[i] - total[i]
        if r > 1.0:
            r = 1.0
        elif r < 0.0:
            r = 0.0
        if r < floor and down[i]:
            below += 1
        command[i] = r
    return below


def warm_up() -> None:
    """Compile (or load from numba's cache) the effects' loops, outside any real-time block.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> len(_adsr.signatures) >= 1
    True
    """
    t = np.zeros(2)
    _adsr(t, 0.1, 0.1, 0.1, 0.1, 1.0, 0.5, np.empty(2))
    flags = np.ones(2, dtype=np.bool_)
    ints = np.zeros(2, dtype=np.int64)
    _find_events(t, t, flags, 2, np.zeros(2), ints, np.zeros((2, 4)), t, flags, np.zeros((2, 1)), ints,
                 np.zeros(2, dtype=np.int64), ints.copy(), ints.copy(), ints.copy())
    out = np.empty(2)
    _oscillate(t, 0, 1.0, 1.0, out)
    _accumulate(t, 0.0, 1.0, math.inf, 0.1, out, np.zeros(2))
    _subtract_clipped(t, t, out)
    _subtract_clipped(t.astype(np.float32), t, out)  # the texture's ratio comes as float32
    _subtract_below(out, t, flags, 0.1)


# ---- evaluation plans: each node owns its scratch buffers --------------------------------------------------
class _Plan:
    def evaluate(self, t: np.ndarray, out: np.ndarray) -> None:
        raise NotImplementedError


class _Oscillator(_Plan):
    KINDS = {Sine: 0, Square: 1, Sawtooth: 2, Triangle: 3}

    def __init__(self, effect, capacity: int):
        self.args = (self.KINDS[type(effect)], effect.frequency_hz, effect.depth)

    def evaluate(self, t, out):
        _oscillate(t, *self.args, out)


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
    """An evaluator for ``effect`` over up to ``capacity`` times at once, with its buffers allocated now.

    Parameters
    ----------
    effect : Effect
    capacity : int
        The most times evaluated at once.

    Returns
    -------
    _Plan
        ``evaluate(t, out)`` writes the effect's values at times ``t`` (s, >= 0) into ``out``, allocating nothing.

    Examples
    --------
    >>> import numpy as np
    >>> from ultraglide.textures.effect_types import Constant
    >>> values = np.empty(3)
    >>> plan(Constant(0.3, 0.05), 3).evaluate(np.array([0.0, 0.02, 0.06]), values)   # s since the trigger
    >>> values.tolist()
    [0.3, 0.3, 0.0]
    """
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
    after its duration.

    Parameters
    ----------
    effect : Effect
    t_s : array_like
        Times (s) since the trigger.

    Returns
    -------
    numpy.ndarray
        Drops in friction ratio.

    Examples
    --------
    >>> from ultraglide.textures.effect_types import ADSR, Constant
    >>> sample(Constant(0.3, 0.05), [-0.01, 0.0, 0.02, 0.06]).tolist()          # s: before, during, after
    [0.0, 0.3, 0.3, 0.0]
    >>> sample(ADSR(0.01, 0.0, 0.0, 0.01, sustain_level=1.0), [0.005, 0.01, 0.015]).round(9).tolist()  # 10 ms up, down
    [0.5, 1.0, 0.5]
    """
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
    (ratios below the model's floor are clamped and counted by the inverse, as for textures; where the renderer
    plans, the effects are subtracted from its command too, and ``below_floor`` counts the touching samples they
    take below the plate's floor there).

    Parameters
    ----------
    bindings : tuple of Binding
        The effects and their triggers.
    control_rate_hz : float
        The rate of the blocks mixed, Hz.
    capacity : int
        The longest block, samples.

    Examples
    --------
    An event's 10 ms drop of 0.3 mixed into a block at rest (ratio 1):

    >>> import numpy as np
    >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
    >>> player = EffectPlayer((Binding(Trigger("event", name="tick"), Constant(0.3, 0.01)),), 12000.0)
    >>> player.trigger("tick", 0.0), player.trigger("no-such-event", 0.0)
    (True, False)
    >>> t = np.arange(24) / 12000.0
    >>> ratio = player.mix(t, np.zeros(24), np.zeros(24), np.ones(24, dtype=bool), np.ones(24, dtype=np.float32))
    >>> ratio[:3].round(6).tolist(), player.starts
    ([0.7, 0.7, 0.7], [(0, 0.0)])
    """

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
        count = len(self.bindings)
        self._kinds = np.array([ON.index(b.trigger.on) for b in self.bindings], dtype=np.int64)
        self._boxes = np.empty((count, 4))
        for k, b in enumerate(self.bindings):
            region = b.trigger.region_mm
            self._boxes[k] = ((-np.inf, -np.inf, np.inf, np.inf) if region is None else
                              (region[0], region[1], region[0] + region[2], region[1] + region[3]))
        self._min_steps = np.array([b.trigger.min_speed_mm_s / self.control_rate_hz for b in self.bindings])
        self._across_y = np.array([b.trigger.axis == "y" for b in self.bindings], dtype=np.bool_)
        self._lines = np.zeros((count, max([1] + [len(b.trigger.lines_mm) for b in self.bindings])))
        self._line_counts = np.array([len(b.trigger.lines_mm) for b in self.bindings], dtype=np.int64)
        for k, b in enumerate(self.bindings):
            self._lines[k, :len(b.trigger.lines_mm)] = b.trigger.lines_mm
        self._state = np.array([-1 if b.trigger.on == "cross" else 0 for b in self.bindings], dtype=np.int64)
        self._previous = np.full(2, math.nan)  # the finger's last position before this block, mm
        self._event_binding = np.empty(EVENTS, dtype=np.int64)
        self._event_index = np.empty(EVENTS, dtype=np.int64)
        self._event_action = np.empty(EVENTS, dtype=np.int64)
        self._down = np.empty(capacity, dtype=np.bool_)
        self._sum = np.empty(capacity)
        self._local = np.empty(capacity)
        self._value = np.empty(capacity)
        self._mixed = np.empty(capacity)
        # the voice pool: binding index (−1 free), start s, gate off s (inf while held)
        # (lists: read per block from Python, where numpy scalars would cost more than they save)
        self.voice_binding = [-1] * VOICES
        self.voice_start = [0.0] * VOICES
        self.voice_gate_off = [math.inf] * VOICES
        self._active = 0  # voices playing
        self.started = 0
        self._log = np.zeros((LOG, 2))  # (binding, start s) of the latest voices, a ring
        self.clipped_samples = 0
        self.below_floor = 0

    def trigger(self, name: str, t_s: float) -> bool:
        """An app's named event at ``t_s`` (perf_counter s; or the offline clock). False: no binding has it.

        Parameters
        ----------
        name : str
            The event's name.
        t_s : float
            When, perf_counter s (or the offline clock).

        Returns
        -------
        bool

        Examples
        --------
        >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
        >>> player = EffectPlayer((Binding(Trigger("event", name="tick"), Constant(0.3, 0.01)),), 12000.0)
        >>> player.trigger("tick", 0.0), player.trigger("tock", 0.0)
        (True, False)
        """
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
        if self.voice_binding[slot] < 0:
            self._active += 1
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
        if math.isnan(self._previous[0]):
            self._previous[0], self._previous[1] = x[0], y[0]
        found = _find_events(x, y, down, n, self._previous, self._kinds, self._boxes, self._min_steps,
                             self._across_y, self._lines, self._line_counts, self._state, self._event_binding,
                             self._event_index, self._event_action)
        for j in range(found):  # a loop over events (a few a second), not samples
            k, t_s, action = int(self._event_binding[j]), float(times[self._event_index[j]]), self._event_action[j]
            if action == RELEASE:
                self._release(k, t_s)
            else:
                self._start(k, t_s, action == PLAY_HELD)

    # ---- the block path ----------------------------------------------------------------------------------
    def mix(self, times, x, y, down, ratio, also: np.ndarray | None = None, also_floor: float = 0.0) -> np.ndarray:
        """The texture's ``ratio`` with the effects playing at ``times`` (s) subtracted, clipped to [0, 1]. The
        array returned is a buffer of the player's, overwritten by the next block (a copy if n > capacity).
        ``also``, if given, has the same effects subtracted in place (the planner's command for the texture); its
        samples pushed below ``also_floor`` while the finger touches are counted in :attr:`below_floor`.

        Parameters
        ----------
        times : numpy.ndarray
            The block's times, s.
        x, y : numpy.ndarray
            The finger's position, mm.
        down : numpy.ndarray
            Whether it touches.
        ratio : numpy.ndarray
            The texture's friction ratio (float32).
        also : numpy.ndarray, optional
            Another ratio of the block's length to subtract the same effects from, in place (clipped to [0, 1]).
        also_floor : float
            The lowest ratio the plate reaches, for counting ``also``'s samples the effects take below it.

        Returns
        -------
        numpy.ndarray

        Examples
        --------
        A 10 ms drop of 0.3 started at 0 s, over a block of 24 samples (2 ms) of a texture at 0.9:

        >>> import numpy as np
        >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
        >>> player = EffectPlayer((Binding(Trigger("event", name="tick"), Constant(0.3, 0.01)),), 12000.0)
        >>> _ = player.trigger("tick", 0.0)
        >>> t = np.arange(24) / 12000.0
        >>> texture = np.full(24, 0.9, dtype=np.float32)
        >>> mixed = player.mix(t, np.zeros(24), np.zeros(24), np.ones(24, dtype=bool), texture)
        >>> sorted(set(mixed.round(6).tolist()))                                   # 0.9 - 0.3
        [0.6]
        """
        n = len(times)
        if n > self.capacity:  # a long catch-up block: in pieces
            out = np.empty(n)
            for start in range(0, n, self.capacity):
                end = min(n, start + self.capacity)
                piece_down = down if np.ndim(down) == 0 else down[start:end]
                out[start:end] = self.mix(times[start:end], x[start:end], y[start:end], piece_down,
                                          ratio[start:end], None if also is None else also[start:end], also_floor)
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
        local, value = self._local[:n], self._value[:n]
        last = float(times[n - 1])
        for v in range(VOICES if self._active else 0):
            k = self.voice_binding[v]
            if k < 0:
                continue
            start, gate_off = self.voice_start[v], self.voice_gate_off[v]
            np.subtract(times, start, out=local)
            self.plans[k].evaluate(local, value)
            duration, release = self.durations[k], self.bindings[k].release_s
            _accumulate(times, start, duration, gate_off, release, value, total)
            if last - start >= duration or (-math.inf < gate_off < math.inf and last >= gate_off + release):
                self.voice_binding[v] = -1
                self._active -= 1
        mixed = self._mixed[:n]
        self.clipped_samples += _subtract_clipped(ratio, total, mixed)  # above rest; below the floor: the inverse's
        if also is not None:
            self.below_floor += _subtract_below(also, total, flags, also_floor)
        return mixed

    @property
    def starts(self) -> list[tuple[int, float]]:
        """(binding index, start time s) of the latest voices (up to 1024), oldest first.

        Returns
        -------
        list of (int, float)

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
        >>> player = EffectPlayer((Binding(Trigger("event", name="tick"), Constant(0.3, 0.01)),), 12000.0)
        >>> _ = player.trigger("tick", 0.001)
        >>> t = np.arange(24) / 12000.0
        >>> _ = player.mix(t, np.zeros(24), np.zeros(24), np.ones(24, dtype=bool), np.ones(24, dtype=np.float32))
        >>> player.starts                                              # binding 0, at 1 ms
        [(0, 0.001)]
        """
        first = max(0, self.started - LOG)
        return [(int(self._log[k % LOG, 0]), float(self._log[k % LOG, 1])) for k in range(first, self.started)]

    @property
    def playing(self) -> int:
        """Voices playing now.

        Examples
        --------
        >>> import numpy as np
        >>> from ultraglide.textures.effect_types import Binding, Constant, Trigger
        >>> player = EffectPlayer((Binding(Trigger("event", name="tick"), Constant(0.3, 0.01)),), 12000.0)
        >>> player.playing
        0
        >>> _ = player.trigger("tick", 0.0)
        >>> t = np.arange(24) / 12000.0
        >>> _ = player.mix(t, np.zeros(24), np.zeros(24), np.ones(24, dtype=bool), np.ones(24, dtype=np.float32))
        >>> player.playing                                             # 2 ms into its 10 ms
        1
        """
        return self._active
