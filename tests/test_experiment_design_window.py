"""A design's window under SDL's dummy driver: ratings, same-different and typed magnitudes, real pygame events in."""

import csv
import threading
import time

import pytest

from ultraglide.experiment import Block, Condition, Design, Stimulus, plan, run

DEADLINE_S = 30.0


@pytest.fixture
def pg(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    import pygame

    return pygame


def wait_for(window, what, number):
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        if window.ready.is_set() and window.showing == (what, number):
            return
        time.sleep(0.005)
    raise AssertionError(f"the window never showed {what} {number}")


def post(pg, kind, **fields):
    pg.event.post(pg.event.Event(kind, **fields))


def key(pg, name):
    post(pg, pg.KEYDOWN, key=pg.key.key_code(name), mod=0, unicode=name if len(name) == 1 else "", scancode=0)


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

    helper = threading.Thread(target=participant, daemon=True)
    helper.start()
    try:
        session = run(design, "P01", out=tmp_path / "s", responder=window)
    finally:
        window.close()
    helper.join(timeout=DEADLINE_S)
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
