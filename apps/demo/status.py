"""The demo's status line, two lines at the top of the screen, fitted to its width.

The first line says what the plate does: the device and its state with its faults, the model, the force
and what the plate's limit did; "H: help" stands at its right end. The second says what is going on
around it: the recording, ``--watch``'s errors, the engine's figures. Where a line is too wide for the
screen, parts give way in order: first their shorter forms, then the least needed parts (the engine's
figures, the force's source), and the parts that must stay (faults, the recording, ``--watch``'s errors,
help) are shortened with an ellipsis, never dropped.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ultraglide.apps.demo.draw import fit_text
from ultraglide.apps.demo.felt import felt_part_words

SEPARATOR = "   ·   "
HELP = "H: help"


@dataclass(frozen=True)
class Part:
    """One part of a status line: its words, a shorter form, whether it must stay, and its rank (the lowest
    rank gives way first)."""

    text: str
    short: str | None = None
    must: bool = False
    rank: int = 0
    warn: bool = False  # drawn in the warning colour


def status_parts(app) -> tuple[list[Part], list[Part]]:
    """The two lines' parts, from the app's state and its engine's status."""
    driver = app.driver
    around = []
    if app.recorder is not None:
        name = app.recorder.path.name
        around.append(Part(f"recording {name}: {app.recorder.rows} touches", f"rec {app.recorder.rows}",
                           must=True, rank=9))
    around += [Part(error, must=True, rank=9, warn=True) for error in app.watch_errors]
    lost = app.engine_lost
    if lost is not None:  # its process died or froze; the device was made safe
        return [Part(f"the engine was lost ({lost.cause}); the device was made safe · R: restart the engine",
                     "engine lost; device made safe · R: restart", must=True, rank=9, warn=True)], around
    if app.link is None:
        plate = [Part("starting the engine (its own process; compiling its kernels)…", "starting the engine…",
                      must=True, rank=9)]
        if driver.unfelt:
            plate.append(Part(f"{driver.unfelt} touches before it was ready: not felt",
                              f"{driver.unfelt} not felt", rank=5))
        return plate, around
    s = app.link.status(0.0)
    device = {"sim": "simulated plate"}.get(s.device, s.device.replace("serial:", "plate on serial ")
                                            .replace("audio:", "audio output ").replace("wav:", "recording "))
    # the engine is paused between touches (the plate rests); the user's pause is the Space key's
    state = "paused" if app.user_paused else ("running" if s.state == "paused" else s.state)
    faults = "faults: " + ", ".join(s.faults) if s.faults else "no faults"
    if s.verdict:  # the plate was lost, cut its output or faulted over this run: the run is not clean
        faults += f" ({s.verdict})"
    source = "touch pressure" if driver.pressure_seen else "Up/Down keys"
    plate = [
        Part(f"{device} {state}, {faults}", f"{s.device} {state}, {faults}", must=True, rank=9,
             warn=bool(s.faults) or bool(s.verdict)),
        Part(f"{app.link.model_name} model", app.link.model_name, rank=6),
        Part(f"{app.force_n:.2f} N ({source})", f"{app.force_n:.2f} N", rank=7),
        limit_part(s.limited_pct, s.limited_samples),
    ]
    felt = felt_part_words(app, time.perf_counter())
    if felt is not None:  # a model with the finger's dynamics: what a swipe at the finger's speed keeps
        plate.append(Part(felt[0], felt[1], rank=5))
    if s.loop:  # the friction loop's state in words: "closed loop: following, error 0.03", "open loop: finger resting"
        plate.append(Part(s.loop, s.loop.split(",")[0], must=True, rank=8, warn=s.loop.startswith("open loop: sensor")))
    around.append(Part(f"{_count(s.underruns, 'underrun')}, {_count(s.late_blocks, 'late block')}, block "
                       f"{s.block_p50_us:.0f}/{s.block_p99_us:.0f} µs p50/p99",
                       f"{_count(s.underruns, 'underrun')}, {s.late_blocks} late", rank=2))
    return plate, around


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def limit_part(limited_pct: float, limited_samples: int) -> Part:
    """What the plate's limit did: the share of the last second it held the drive, and the samples it held on
    this texture since it was shown (none: the texture asks for nothing beyond the plate)."""
    if limited_samples == 0:
        return Part("within the plate's limit on this texture", "within the limit", rank=8)
    return Part(f"held at the limit {limited_pct:.0f} % of the last second ({limited_samples} samples on this "
                "texture)", f"at the limit {limited_pct:.0f} %", rank=8)


def fit_parts(font, parts: list[Part], width_px: int) -> list[tuple[str, Part]]:
    """The parts' words that fit in ``width_px`` with separators: shorter forms first, then the lowest ranks
    dropped, then what must stay shortened with an ellipsis."""
    words = {id(part): part.text for part in parts}
    kept = list(parts)

    def width() -> int:
        return font.size(SEPARATOR.join(words[id(part)] for part in kept))[0]

    for part in sorted(parts, key=lambda part: part.rank):  # shorter forms, least needed first
        if width() <= width_px:
            break
        if part.short is not None:
            words[id(part)] = part.short
    for part in sorted(parts, key=lambda part: part.rank):  # then the parts that may go
        if width() <= width_px:
            break
        if not part.must:
            kept.remove(part)
    while width() > width_px and kept:  # then the longest of what must stay, shortened
        longest = max(kept, key=lambda part: font.size(words[id(part)])[0])
        others = font.size(SEPARATOR.join(words[id(part)] for part in kept if part is not longest))[0]
        room = width_px - others - (font.size(SEPARATOR)[0] if len(kept) > 1 else 0)
        shortened = fit_text(font, words[id(longest)], max(room, font.size("a…")[0]))
        if shortened == words[id(longest)]:
            break  # nothing left to shorten
        words[id(longest)] = shortened
    return [(words[id(part)], part) for part in kept]


def status_lines(app, font, width_px: int, margin_px: int = 8) -> tuple[list, list]:
    """The two lines as (words, Part) pairs fitted to the width; the first leaves room for "H: help"."""
    plate, around = status_parts(app)
    help_w = font.size(SEPARATOR + HELP)[0]
    return (fit_parts(font, plate, width_px - 2 * margin_px - help_w),
            fit_parts(font, around, width_px - 2 * margin_px))


def status_words(app) -> str:
    """Everything the status line says, unfitted, on one line (for scripts and tests)."""
    plate, around = status_parts(app)
    return SEPARATOR.join(part.text for part in plate + around + [Part(HELP)])
