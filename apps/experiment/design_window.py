"""The participant's window for a design (``ultraglide experiment run DESIGN.toml``): every task of a design.

The threshold sessions' window (:mod:`ultraglide.apps.experiment.window`), laid out afresh for each trial from
its :class:`~ultraglide.experiment.runner.Presentation`: the trial's zones, its question and its answer buttons
labelled in the participant's language. How each task answers:

* forced choice: a button under each zone (or its number's key, ←/→); yes/no: the two buttons (Y/N keys);
* same-different: the two buttons (S/D keys), the second meaning "different";
* rating: a button for each point of the scale (or the digit of its position, from 1);
* magnitude estimation: a number typed (digits, a decimal point, Backspace) and Enter;
* adjustment: − and + (or ←/→) step the second zone's contrast by 1 dB, the plate showing each step at once; OK
  (or Enter) gives the level set.

It is the participant-interface seam's window implementation (:mod:`ultraglide.experiment.responders`).
"""

from __future__ import annotations

from types import SimpleNamespace

from ultraglide.apps.experiment.window import WindowResponder

from ultraglide.experiment.responders import Answer

MAX_TYPED = 12


class DesignWindow(WindowResponder):
    """Presents a design's trials; see the module docstring."""

    def __init__(self, design, device: str = "sim", screen_width_mm: float | None = None, windowed: bool = False,
                 size=(1280, 800), output=None):
        from ultraglide.experiment.design import plan
        from ultraglide.experiment.stimuli import Layout

        self.total = len(plan(design))
        self.words = design.word  # the participant's words: the design's [words], English by default
        config = SimpleNamespace(device=device, profile=design.profile, model=design.model, force_n=design.force_n,
                                 closed_loop=False, intervals=2, total_trials=self.total, question="")
        layout = SimpleNamespace(layout=Layout(2, tuple(design.zone_mm), design.gap_mm))
        self.mode = "choice"
        self.typed = ""
        self.low = 0
        super().__init__(config, layout, screen_width_mm, windowed, size, output)

    def _prepare(self, shown) -> None:
        """Lay the window out for this trial: its zones, question and buttons."""
        task = shown.trial.task
        intervals = shown.intervals
        self.mode = ("yes_no" if task == "constant" and intervals == 1 else "choice" if intervals > 1 else
                     "pair" if task == "same_different" else task)
        self.config = SimpleNamespace(**{**vars(self.config), "intervals": max(intervals, 1) if self.mode == "choice"
                                         else 1, "question": shown.question})
        self.design = SimpleNamespace(layout=shown.layout)
        self._layout()
        labels = list(shown.labels)
        pg = self.pg
        top = self.canvas.bottom + 20
        if self.mode == "choice":
            self.buttons = [(label, rect) for label, (_, rect) in zip(labels, self.buttons, strict=True)]
        elif self.mode in ("yes_no", "pair"):
            self.buttons = [(labels[0], self.buttons[0][1]), (labels[1], self.buttons[1][1])]
        elif self.mode in ("rating", "adjustment"):
            self.low = shown.scale[0] if shown.scale else 0
            self.adjusting = shown
            width = min(120, (self.screen.get_width() - 40) // len(labels) - 10)
            left = self.canvas.centerx - (len(labels) * (width + 10) - 10) // 2
            self.buttons = [(label, pg.Rect(left + i * (width + 10), top, width, 70)) for i, label in enumerate(labels)]
        else:  # magnitude: a typed number; the modulus is said in the question's line
            self.typed = ""
            self.buttons = [(self.words("ok"), pg.Rect(self.canvas.centerx - 60, top + 80, 120, 70))]
            self.config.question = f"{shown.question} {self.words('modulus', modulus=f'{shown.modulus:g}')}"

    def _progress(self, trial: int, total: int) -> str:
        return self.words("progress", trial=trial, total=total)

    def _draw_trial(self, trial: int) -> None:
        super()._draw_trial(trial)
        if self.mode == "magnitude":
            box = self.pg.Rect(self.canvas.centerx - 120, self.canvas.bottom + 20, 240, 60)
            self.pg.draw.rect(self.screen, (240, 240, 240), box, 2, border_radius=6)
            self._text(self.typed or "…", box.center, self.big_font)
            self.pg.display.flip()

    def _step(self, direction: int) -> None:
        """The adjusted zone's contrast one dB up or down, within its range, shown on the plate at once."""
        shown = self.adjusting
        low, high = shown.level_range
        self.level = float(min(max(self.level * 10 ** (direction / 20), low), high))
        self.output.show(shown.texture_at(self.level), shown.trial.number)

    def _answer_for(self, x: float, y: float):
        for index, (_, rect) in enumerate(self.buttons):
            if rect.collidepoint(x, y):
                if self.mode == "adjustment":
                    if index == 2:
                        return self.level
                    self._step(-1 if index == 0 else +1)
                    return None
                if self.mode == "yes_no":
                    return int(index == 0)
                if self.mode == "magnitude":
                    return self._typed_number()
                return index
        return None

    def _typed_number(self):
        try:
            value = float(self.typed)
        except ValueError:
            return None
        return value if value >= 0 else None

    def _key_answer(self, key):
        name = self.pg.key.name(key)
        if self.mode == "pair":
            return {"s": 0, "d": 1}.get(name)
        if self.mode == "adjustment":
            if name in ("return", "enter"):
                return self.level
            if name in ("left", "right", "-", "+", "=", "minus", "plus", "equals"):
                self._step(-1 if name in ("left", "-", "minus") else +1)
            return None
        if self.mode == "rating":
            if name.isdigit() and 1 <= int(name) <= len(self.buttons):
                return int(name) - 1
            return None
        if self.mode == "magnitude":
            if name in ("return", "enter"):
                return self._typed_number()
            if name == "backspace":
                self.typed = self.typed[:-1]
            elif (name.isdigit() or (name in (".", "period") and "." not in self.typed)) and len(
                    self.typed) < MAX_TYPED:
                self.typed += "." if name in (".", "period") else name
            self._draw_trial(self.showing[1])
            return None
        return super()._key_answer(key)

    def present(self, shown) -> Answer:
        """Show the trial (its texture on the plate, its question and buttons) and wait for the answer."""
        self._prepare(shown)
        self.level = shown.level
        self.output.show(shown.texture(), shown.trial.number)
        answer = self._wait_answer(shown.trial.number)
        if not answer.quit and self.mode == "rating":
            answer.response = self.low + answer.response
        friction = getattr(self.output, "trial_friction", None)
        if friction is not None and not answer.quit:
            answer.friction = friction(self.touched_s)  # the previous trial's ramp down is not this one's
        return answer

    def _draw_break(self, trial: int) -> None:
        self.screen.fill((24, 26, 30))
        centre = self.screen.get_rect().center
        self._text(self.break_message, centre, self.big_font)
        self.pg.display.flip()

    def take_break(self, trial: int, message: str = "") -> bool:
        self.break_message = message or "Take a break. Tap or press space to go on."
        return super().take_break(trial)
