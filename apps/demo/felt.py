"""What the finger keeps of the shown texture's contrast at its own speed, for the demo's status line.

With a model that has the finger's friction dynamics (``--model dynamic``), a fine texture swept fast is felt
with less contrast than it asks (``render.planning``). :class:`FeltContrast` works out, once per texture and
model and in a thread of its own (a swipe rendered at five speeds takes about a tenth of a second), what a swipe
keeps at 25-400 mm/s, planned and asked instantly; the status line reads it at the finger's speed, taken from the
driving finger's last 150 ms, or its last three reports on a UI too busy to read three in that time
(:func:`finger_speed_mm_s`).
"""

from __future__ import annotations

import math
import threading

import numpy as np

SPEEDS_MM_S = (25.0, 50.0, 100.0, 200.0, 400.0)
SPEED_WINDOW_S = 0.15  # the finger's speed: its path over this long
LONGEST_SPEED_WINDOW_S = 0.5  # or over its last three reports, when a busy UI read fewer in that time, up to this
MIN_SPEED_MM_S = 5.0  # slower than this the finger is taken as resting: no figure
FloorKey = tuple[tuple[float, float], ...]  # a floor asked for, comparable: (speed mm/s, floor) pairs


def finger_speed_mm_s(trace, mm_per_px: float, now_s: float) -> float | None:
    """The driving finger's speed over its last :data:`SPEED_WINDOW_S` (path length / time), mm/s; None when it
    rests or has too few reports. A UI busy drawing (a loaded machine) may read fewer than three reports in that
    time: then the last three, if they came within :data:`LONGEST_SPEED_WINDOW_S`. ``trace``: ``(perf_counter s,
    x px, y px)`` tuples, oldest first."""
    recent = [(t, x, y) for t, x, y in trace if now_s - t <= SPEED_WINDOW_S]
    if len(recent) < 3:
        recent = list(trace)[-3:]
        if len(recent) < 3 or now_s - recent[0][0] > LONGEST_SPEED_WINDOW_S:
            return None
    t, x, y = (np.array(column, dtype=float) for column in zip(*recent, strict=True))
    span = t[-1] - t[0]
    if span <= 0:
        return None
    speed = float(np.sum(np.hypot(np.diff(x), np.diff(y)))) * mm_per_px / span
    return speed if speed >= MIN_SPEED_MM_S else None


class FeltContrast:
    """The contrast a swipe keeps, per (texture, model), worked out in the background on request, for the floor it
    was asked with: asked again with another floor (the force changed: the floor within the limit with it), the
    figures are worked out anew and none are given until they are."""

    def __init__(self):
        self._lock = threading.Lock()
        # (texture, model) -> (the floor asked, its rows; None while under way)
        self._table: dict[tuple[int, str], tuple[FloorKey, list[tuple[float, float, float]] | None]] = {}

    def request(self, texture, model_name: str, model, floor) -> None:
        """Work out the figures for ``texture`` under ``model`` (one with ``dynamics``) unless done or under way
        for this ``floor``: the lowest friction ratio the plate reaches (the model at the plate's limit), one for
        every speed or, under a speed law, a mapping from each of :data:`SPEEDS_MM_S` to the floor at that speed."""
        key, asked = (id(texture), model_name), _floor_key(floor)
        with self._lock:
            if key in self._table and self._table[key][0] == asked:
                return
            self._table[key] = (asked, None)  # under way
        threading.Thread(target=self.work_out, args=(texture, model_name, model.dynamics, floor),
                         name="felt-contrast", daemon=True).start()

    def work_out(self, texture, model_name: str, dynamics, floor) -> None:
        """The figures for ``texture`` under ``model_name`` with these ``dynamics``, worked out in this thread;
        kept unless another floor was asked for meanwhile, and given up between speeds once one was (a force key
        held down asks for a floor at each step: the threads it starts end early instead of piling up)."""
        from ultraglide.render.planning import swipe_contrast

        key, asked = (id(texture), model_name), _floor_key(floor)
        rows = []
        for speed in SPEEDS_MM_S:
            with self._lock:
                if key in self._table and self._table[key][0] != asked:
                    return
            kept = swipe_contrast(texture, dynamics, speed, floor[speed] if isinstance(floor, dict) else floor,
                                  longest_s=0.5)
            rows.append((speed, kept.planned, kept.instantaneous))
        with self._lock:
            if key not in self._table or self._table[key][0] == asked:
                self._table[key] = (asked, rows)

    def at(self, texture, model_name: str, speed_mm_s: float) -> tuple[float, float] | None:
        """(planned, instantaneous) contrast kept at ``speed_mm_s``, interpolated in log speed between the worked
        speeds (held at the ends); None until worked out."""
        with self._lock:
            rows = self._table.get((id(texture), model_name), (None, None))[1]
        if not rows:
            return None
        logs = [math.log(speed) for speed, _, _ in rows]
        where = min(max(math.log(speed_mm_s), logs[0]), logs[-1])
        planned = float(np.interp(where, logs, [row[1] for row in rows]))
        instantaneous = float(np.interp(where, logs, [row[2] for row in rows]))
        return planned, instantaneous


def _floor_key(floor) -> FloorKey:
    """A floor as :meth:`FeltContrast.request` takes it (one number, or one per speed), comparable."""
    if isinstance(floor, dict):
        return tuple(sorted((float(speed), float(value)) for speed, value in floor.items()))
    return ((0.0, float(floor)),)


MAX_PIXELS = 4_000_000  # a larger map would be resampled for the lookup: not worked out for a status line


def felt_part_words(app, now_s: float) -> tuple[str, str] | None:
    """The status line's words for the contrast felt at the finger's speed (long, short), or None: a model
    without dynamics, a gradient or very large texture, a resting finger, or figures not worked out yet."""
    model = _dynamic_model(app.link.model_name)
    texture = getattr(app.scenes, "current", None)
    if model is None or texture is None or getattr(texture, "kind", "") != "friction" \
            or texture.cols * texture.rows > MAX_PIXELS:
        return None
    from ultraglide.render.physics.speed_law import floor_at_speed, speed_law_of

    limit = app.link.profile.max_amplitude_um_pp
    if speed_law_of(model) is None:
        floor = floor_at_speed(model, app.force_n, 22.0, limit)
    else:  # under a settled speed law the floor rises with speed
        floor = {speed: floor_at_speed(model, app.force_n, speed, limit) for speed in SPEEDS_MM_S}
    app.felt.request(texture, app.link.model_name, model, floor)
    speed = finger_speed_mm_s(app.driver.trace, app.mm_per_px, now_s)
    kept = app.felt.at(texture, app.link.model_name, speed) if speed is not None else None
    if kept is None:
        return None
    planned, instantaneous = kept
    return (f"felt at {speed:.0f} mm/s: {100 * planned:.0f} % of its contrast (asked instantly, "
            f"{100 * instantaneous:.0f} %)", f"felt {100 * planned:.0f} %")


_models: dict[str, object] = {}


def _dynamic_model(name: str):
    """The model named ``name`` if it has the finger's friction dynamics, else None (loaded once per name)."""
    if name not in _models:
        from ultraglide.render.physics.calibration import load_model

        from ultraglide.errors import UltraglideError

        try:
            model = load_model(name)
        except (UltraglideError, OSError):  # the engine reports a bad model; the status line just has no figure
            model = None
        _models[name] = model if getattr(model, "dynamics", None) is not None else None
    return _models[name]
