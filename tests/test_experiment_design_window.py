"""A design's window under SDL's dummy driver: ratings, same-different and typed magnitudes, real pygame events in."""

import csv
import time

import pytest
from participant import DEADLINE_S, Participant, key, post, wait_for

from ultraglide.experiment import Block, Condition, Design, Stimulus, plan, run


@pytest.fixture
def pg(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    import pygame

    return pygame


@pytest.mark.slow
def test_a_participant_rates_compares_and_estimates_through_the_window(pg, tmp_path):
    from ultraglide.apps.experiment.design_window import DesignWindow
    from ultraglide.apps.experiment.output import LocalOutput

    stimuli = {"a": Stimulus("a", "grating-1mm", contrast=0.3), "b": Stimulus("b", "grating-2mm", contrast=0.3)}
    design = Design("window", stimuli, {"ab": Condition("ab", "a", "b")},
                    (Block("rate", "rating", ("ab",), repeats=2, scale=(1, 3), labels=("lisse", "moyen", "rugueux"),
                           question="Quelle rugosité ?"),
                     Block("pair", "same_different", ("ab",), repeats=1),
                     Block("number", "magnitude", ("ab",), repeats=1, modulus=10.0, modulus_stimulus="b"),
                     Block("match", "adjustment", ("ab",), repeats=1)), seed=2)
    trials = plan(design)
    output = LocalOutput("null", design.profile, design.model, design.force_n)
    window = DesignWindow(design, "null", 338.7, True, output=output)
    seen = {}

    def participant():
        for trial in trials:
            if trial.break_before:
                wait_for(window, "break", trial.number)
                key(pg, "space")
            wait_for(window, "trial", trial.number)
            seen[trial.number] = [label for label, _ in window.buttons], window.config.question
            if trial.task == "rating":  # the first trial by a tap on the third button, the second by its digit
                if trial.number == 1:
                    x, y = window.buttons[2][1].center
                    w, h = window.screen.get_size()
                    post(pg, pg.FINGERDOWN, x=x / w, y=y / h, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
                else:
                    key(pg, "1")
            elif trial.task == "same_different":
                key(pg, "d" if trial.zones[0] != trial.zones[1] else "s")
            elif trial.task == "adjustment":  # three steps up by key, one down by the − button, then OK by a click
                for name in ("right", "right", "right"):
                    key(pg, name)
                post(pg, pg.MOUSEBUTTONDOWN, pos=window.buttons[0][1].center, button=1, touch=False)
                post(pg, pg.MOUSEBUTTONDOWN, pos=window.buttons[2][1].center, button=1, touch=False)
            else:
                for name in ("1", "2", "x", "backspace", "2", ".", "5"):
                    key(pg, name)
                wait_until = time.monotonic() + DEADLINE_S
                while window.typed != "12.5" and time.monotonic() < wait_until:
                    time.sleep(0.005)
                key(pg, "return")

    with Participant(pg, window, participant):
        try:
            session = run(design, "P01", out=tmp_path / "s", responder=window)
        finally:
            window.close()
    with open(tmp_path / "s" / "trials.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert session.complete and len(rows) == len(trials) == 2 + 4 + 1 + 1
    assert [r["response"] for r in rows[:2]] == ["3", "1"]
    assert [r["response_label"] for r in rows[:2]] == ["rugueux", "lisse"]
    assert seen[1] == (["lisse", "moyen", "rugueux"], "Quelle rugosité ?")
    pairs = rows[2:6]
    assert all(r["correct"] == "1" for r in pairs)
    assert {r["response"] for r in pairs} == {"same", "different"}
    assert seen[3][0] == ["Same", "Different"]
    assert float(rows[6]["response"]) == 12.5 and "zone 1 = 10" in seen[7][1]
    assert [r["break_before"] for r in rows] == ["0", "0", "1", "0", "0", "0", "1", "1"]
    start = trials[7].level
    assert float(rows[7]["level"]) == start and seen[8][0] == ["−", "+", "OK"]
    assert float(rows[7]["response"]) == pytest.approx(min(start * 10 ** (2 / 20), 0.6), rel=1e-9)
    assert all(float(r["rt_s"]) > 0 for r in rows)


def stroke(pg, window, zone_index, seconds=0.6, steps=60):
    """A finger drawn across a zone left to right along its middle, paced as a finger moves (60 reports)."""
    w, h = window.screen.get_size()
    zone = window.zones[zone_index]
    y = zone.centery / h
    post(pg, pg.FINGERDOWN, x=(zone.left + 2) / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
    started = time.monotonic()
    for k in range(1, steps + 1):
        due = started + seconds * k / steps
        time.sleep(max(0.0, due - time.monotonic()))  # a finger's own pace, not a wait for anything
        x = (zone.left + 2 + (zone.width - 4) * k / steps) / w
        post(pg, pg.FINGERMOTION, x=x, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
    post(pg, pg.FINGERUP, x=x, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)


@pytest.mark.slow
def test_a_design_runs_live_through_the_real_time_engine_and_logs_what_it_played(pg, tmp_path):
    from ultraglide.apps.experiment.design_window import DesignWindow

    stimuli = {"coarse": Stimulus("coarse", "grating-2mm", contrast=0.4, mean=0.7),
               "plain": Stimulus("plain", "grating-2mm", contrast=0.0)}
    design = Design("live", stimuli, {"coarse": Condition("coarse", "coarse"), "plain": Condition("plain", "plain")},
                    (Block("rate", "rating", ("coarse", "plain"), repeats=1, scale=(1, 5)),), seed=4)
    trials = plan(design)
    window = DesignWindow(design, "sim", 338.7, True)  # the engine in its own process, on the simulated plate
    assert window.output.kind == "engine"

    def participant():
        for trial in trials:
            wait_for(window, "trial", trial.number)
            stroke(pg, window, 0)
            key(pg, "3")

    with Participant(pg, window, participant):
        try:
            session = run(design, "P02", out=tmp_path / "s", responder=window)
        finally:
            window.close()
    with open(tmp_path / "s" / "trials.csv", newline="", encoding="utf-8") as handle:
        rows = {row["condition"]: row for row in csv.DictReader(handle)}
    assert session.complete and set(rows) == {"coarse", "plain"}
    # what the engine played while the finger touched: the stimulus's mean friction (0.7, shifted there), and
    # vibration for it; the plain zone at rest asks 1.0 and no vibration
    assert float(rows["coarse"]["target_ratio"]) == pytest.approx(0.7, abs=0.05)
    assert float(rows["coarse"]["commanded_um_pp"]) > 1.0
    assert float(rows["plain"]["target_ratio"]) == pytest.approx(1.0, abs=0.01)
    assert float(rows["plain"]["commanded_um_pp"]) == 0.0


@pytest.mark.slow
def test_the_window_draws_the_design_s_words(pg, tmp_path):
    """The design's [words] at the window as on the page: its progress line, the magnitude estimate's OK button and
    the modulus's words (drawn through the window's own text function, read as it draws)."""
    from ultraglide.apps.experiment.design_window import DesignWindow
    from ultraglide.apps.experiment.output import LocalOutput

    stimuli = {"a": Stimulus("a", "grating-1mm", contrast=0.3), "b": Stimulus("b", "grating-2mm", contrast=0.3)}
    design = Design("mots", stimuli, {"ab": Condition("ab", "a", "b")},
                    (Block("number", "magnitude", ("ab",), repeats=1, modulus=10.0, modulus_stimulus="b",
                           question="Combien ?"),), seed=2,
                    words={"progress": "Essai {trial} sur {total}", "ok": "Valider",
                           "modulus": "(la zone 1 vaut {modulus})"})
    output = LocalOutput("null", design.profile, design.model, design.force_n)
    window = DesignWindow(design, "null", 338.7, True, output=output)
    drawn = []
    draw = window._text
    window._text = lambda text, *rest: (drawn.append(text), draw(text, *rest))[1]

    def participant():
        wait_for(window, "trial", 1)
        for name in ("4", "return"):
            key(pg, name)

    with Participant(pg, window, participant):
        try:
            session = run(design, "P01", responder=window)
        finally:
            window.close()
    assert session.complete and session.trials[0]["response"] == 4.0
    assert "Essai 1 sur 1" in drawn and "Combien ? (la zone 1 vaut 10)" in drawn and "Valider" in drawn
    assert not any("Trial" in text or text == "OK" for text in drawn)
