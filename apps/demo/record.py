"""Recording the demo's touches as a touch log that ``export --trajectory`` and ``play --trajectory`` replay.

The file is ``t_s,x_mm,y_mm,force_n`` (seconds from the first recorded touch, millimetres on the
texture from its top-left corner, newtons) after ``#`` comment lines that give the texture's name
and the screen's geometry as JSON. Rows are flushed as they are written to ``FILE.csv.part``, so a
crash loses nothing; closing renames it to ``FILE.csv``. Lifting the finger and changing texture are
``#`` comment lines too, so every reader of touch logs reads the file (a reader that ignores them
joins the strokes).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ultraglide.atomic import AtomicFile

HEADER = "t_s,x_mm,y_mm,force_n"


class TouchRecorder:
    """Writes touches as they happen; ``close()`` finalises the file (idempotent)."""

    def __init__(self, path: str | Path, default_force_n: float = 0.5):
        self.path = Path(path)
        if self.path.suffix.lower() != ".csv":
            raise ValueError(f"the recording must be a .csv file, got {self.path}")
        self._target = AtomicFile(self.path, partial=True)  # FILE.csv.part; never renamed over a non-file
        self.partial = self._target.temporary
        self._file = open(self.partial, "w", newline="", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self._t0: float | None = None
        self._texture: str | None = None
        self.rows = 0
        self.default_force_n = default_force_n

    def touch(self, t_s: float, x_mm: float, y_mm: float, force_n: float | None, texture: str,
              geometry: dict) -> None:
        """One touch on ``texture`` (perf_counter seconds, mm, N or None for the default force)."""
        if self._t0 is None:
            self._t0 = t_s
            meta = {"texture": texture, **geometry}
            self._file.write(f"# ultraglide demo touch log\n# {json.dumps(meta)}\n{HEADER}\n")
            self._texture = texture
        elif texture != self._texture:
            self._file.write(f"# texture {json.dumps(texture)} from t_s={t_s - self._t0:.6f}\n")
            self._texture = texture
        force = self.default_force_n if force_n is None or math.isnan(force_n) else force_n
        self._file.write(f"{t_s - self._t0:.6f},{x_mm:.4f},{y_mm:.4f},{force:.4f}\n")
        self._file.flush()
        self.rows += 1

    def lift(self, t_s: float) -> None:
        if self._t0 is not None:
            self._file.write(f"# lift at t_s={t_s - self._t0:.6f}\n")
            self._file.flush()

    def close(self) -> Path | None:
        """Rename the finished log into place; with no touch recorded, remove it and return None."""
        if self._file.closed:
            return self.path if self.path.exists() else None
        self._file.close()
        if self.rows < 2:
            self._target.discard()
            return None
        return self._target.commit()
