"""The participant's window under SDL's dummy driver: real pygame events in, the log checked."""

import contextlib
import csv
import io
import json
import os
import subprocess
import sys
import time

import conftest
import numpy as np
import pytest
from participant import DEADLINE_S, Participant, post, wait_for
from PIL import Image
from ultraglide.apps.commands.experiment import design_for
from ultraglide.apps.experiment.session import SessionConfig, run_session
from xvfb import start_xvfb
from xvfb_demo import process_cpu_s, tools_missing

from ultraglide.experiment.procedures import interval_positions


@pytest.fixture
def pg(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    import pygame

    return pygame


def make_window(config):
    from ultraglide.apps.experiment.output import LocalOutput
    from ultraglide.apps.experiment.window import WindowResponder

    design = design_for(config)
    output = LocalOutput("null", config.profile, config.model, config.force_n)
    felt = []  # the friction ratio the renderer looked up under the finger, while it was down

    def observe(block):  # on the device's thread: a block's down may be one bool before any touch
        down = np.broadcast_to(block.down, block.ratio.shape)
        if down.any():
            felt.append(float(block.ratio[down].min()))

    output.renderer.observers.append(observe)
    return WindowResponder(config, design, screen_width_mm=338.7, windowed=True, output=output), design, felt


def swipe(pg, window, zone_index):
    """A finger across one zone's middle, left to right, as touch events (normalised coordinates)."""
    w, h = window.screen.get_size()
    zone = window.zones[zone_index]
    xs = np.linspace(zone.left + 5, zone.right - 5, 40)
    y = zone.centery / h
    post(pg, pg.FINGERDOWN, x=xs[0] / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
    for x in xs[1:]:
        post(pg, pg.FINGERMOTION, x=x / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
        time.sleep(0.008)
    post(pg, pg.FINGERUP, x=xs[-1] / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)


def read_rows(directory):
    with open(directory / "trials.csv", newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.slow
def test_a_participant_swipes_taps_clicks_and_keys_through_a_session_with_a_break(pg, tmp_path):
    config = SessionConfig(texture="grating-1mm", method="staircase", intervals=3, trials=6, seed=5,
                           break_every=4, device="null", bootstrap=20, start_level=0.5)
    window, design, felt = make_window(config)
    targets = interval_positions(config.seed, 6, 3)
    # the answers the participant gives: right, wrong, right, right, wrong, right; each a different way
    plan = [("key", True), ("tap", False), ("click", True), ("key", True), ("click", False), ("tap", True)]

    def participant():
        for trial, (how, right) in enumerate(plan, start=1):
            if trial == 5:
                wait_for(window, "break", 5)
                post(pg, pg.KEYDOWN, key=pg.K_SPACE, mod=0, unicode=" ", scancode=44)
            wait_for(window, "trial", trial)
            target = targets[trial - 1]
            if trial == 1:
                swipe(pg, window, target)
            answer = target if right else (target + 1) % 3
            time.sleep(0.15)
            if how == "key":
                key = pg.key.key_code(str(answer + 1))
                post(pg, pg.KEYDOWN, key=key, mod=0, unicode=str(answer + 1), scancode=0)
            else:
                x, y = window.buttons[answer][1].center
                if how == "click":
                    post(pg, pg.MOUSEBUTTONDOWN, pos=(x, y), button=1, touch=False)
                else:
                    w, h = window.screen.get_size()
                    post(pg, pg.FINGERDOWN, x=x / w, y=y / h, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)

    with Participant(pg, window, participant):
        try:
            outcome = run_session(config, design, window, tmp_path, figures=False)
        finally:
            window.close()
    rows = read_rows(tmp_path)
    assert [r["correct"] for r in rows] == ["1", "0", "1", "1", "0", "1"]
    assert [int(r["target"]) for r in rows] == [t + 1 for t in targets]
    assert all(float(r["rt_s"]) >= 0.15 for r in rows)
    assert [r["break_before"] for r in rows] == ["0", "0", "0", "0", "1", "0"]
    assert outcome.complete and json.loads((tmp_path / "session.json").read_text())["status"] == "complete"
    assert window.output.touches >= 40
    assert min(felt) == pytest.approx(0.5, abs=0.08)  # the first trial's grating at contrast 0.5, under the finger


@pytest.mark.slow
def test_escape_stops_the_session_and_resume_continues_it(pg, tmp_path):
    config = SessionConfig(texture="grating-1mm", method="quest", intervals=2, trials=4, seed=2, device="null",
                           bootstrap=20)
    window, design, _ = make_window(config)

    def participant(keys):
        for trial, key in keys:
            wait_for(window, "trial", trial)
            post(pg, pg.KEYDOWN, key=key, mod=0, unicode="", scancode=0)

    with Participant(pg, window, participant, [(1, pg.K_1), (2, pg.K_ESCAPE)]):
        try:
            outcome = run_session(config, design, window, tmp_path, figures=False)
        finally:
            window.close()
    assert not outcome.complete and len(read_rows(tmp_path)) == 1
    assert json.loads((tmp_path / "session.json").read_text())["status"] == "stopped"

    window, design, _ = make_window(config)
    with Participant(pg, window, participant, [(2, pg.K_2), (3, pg.K_1), (4, pg.K_2)]):
        try:
            outcome = run_session(config, design, window, tmp_path, resume=True, figures=False)
        finally:
            window.close()
    rows = read_rows(tmp_path)
    assert [r["trial"] for r in rows] == ["1", "2", "3", "4"] and outcome.complete
    assert [r["response"] for r in rows] == ["1", "2", "1", "2"]


@pytest.mark.slow
def test_trials_are_felt_through_the_real_time_engine(pg, tmp_path):
    """The default output is the engine process (device null): a swipe over the target zone reaches it and
    the engine looks up the trial's texture there (1 - contrast at the grating's most slippery)."""
    from ultraglide.apps.experiment.output import EngineOutput
    from ultraglide.apps.experiment.window import WindowResponder

    config = SessionConfig(texture="grating-1mm", method="staircase", intervals=2, trials=1, seed=1, device="null",
                           start_level=0.4)
    design = design_for(config)
    window = WindowResponder(config, design, screen_width_mm=338.7, windowed=True)
    assert isinstance(window.output, EngineOutput)
    target = interval_positions(config.seed, 1, 2)[0]

    def participant():
        wait_for(window, "trial", 1)
        swipe(pg, window, target)
        time.sleep(0.2)
        post(pg, pg.KEYDOWN, key=pg.key.key_code(str(target + 1)), mod=0, unicode="", scancode=0)

    with Participant(pg, window, participant):
        try:
            run_session(config, design, window, tmp_path)
            engine = window.output.engine  # it takes the touches from its ring as it renders: wait until it has

            def felt():
                status = engine.status(history_s=30.0)
                return status.touches >= 40 and float(status.history.target_ratio.min()) < 0.65
            conftest.wait_for(felt, DEADLINE_S)
            status = engine.status(history_s=30.0)
        finally:
            window.close()
    assert status.touches >= 40 and status.touches_dropped == 0
    assert float(status.history.target_ratio.min()) == pytest.approx(0.6, abs=0.05)
    assert read_rows(tmp_path)[0]["correct"] == "1"


@pytest.mark.slow
def test_a_closed_loop_trial_logs_the_target_the_measured_friction_and_the_amplitude(pg, tmp_path):
    """--closed-loop on sim: the plate's force sensors under a simulated finger measure the friction of the trial's
    swipes; the trial's row holds the mean target, the mean measured ratio, the mean amplitude sent and the loop's
    words."""
    from ultraglide.apps.experiment.window import WindowResponder

    config = SessionConfig(texture="grating-1mm", method="staircase", intervals=2, trials=1, seed=1, device="sim",
                           start_level=0.4, closed_loop=True)
    design = design_for(config)
    window = WindowResponder(config, design, screen_width_mm=338.7, windowed=True)
    target = interval_positions(config.seed, 1, 2)[0]

    def participant():
        wait_for(window, "trial", 1)
        w, h = window.screen.get_size()
        zone = window.zones[target]
        y = zone.centery / h
        xs = np.linspace(zone.left + 5, zone.right - 5, 40)
        xs = np.concatenate([xs, xs[::-1], xs, xs[::-1]])  # back and forth for about 1.3 s: the loop learns
        post(pg, pg.FINGERDOWN, x=xs[0] / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
        for x in xs[1:]:
            post(pg, pg.FINGERMOTION, x=x / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
            time.sleep(0.008)
        post(pg, pg.FINGERUP, x=xs[-1] / w, y=y, dx=0.0, dy=0.0, finger_id=1, touch_id=1, pressure=1.0)
        time.sleep(0.2)
        post(pg, pg.KEYDOWN, key=pg.key.key_code(str(target + 1)), mod=0, unicode="", scancode=0)

    with Participant(pg, window, participant):
        try:
            run_session(config, design, window, tmp_path, figures=False)
        finally:
            window.close()
    row = read_rows(tmp_path)[0]
    target_ratio, measured = float(row["target_ratio"]), float(row["measured_ratio"])
    assert 0.6 <= target_ratio < 1.0  # the grating of contrast 0.4 under the swipe: ratios 0.6-1
    assert abs(measured - target_ratio) < 0.15  # what the sensors measured, near it
    assert 0.0 < float(row["commanded_um_pp"]) <= 6.0
    assert row["loop"].startswith(("closed loop", "open loop")), row["loop"]


@pytest.mark.slow
@pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_the_participants_window_takes_no_cpu_while_it_waits_for_an_answer(tmp_path):
    """A session on a real X server (Xvfb), its first trial on screen, nobody answering: the command's own process
    (the window and the session; the engine is a process of its own) sleeps until an event comes: at most 1 % of
    a core (measured 0.25 %; looking for events every millisecond took 2.75 %, on a loaded machine)."""
    with session_on_xvfb(tmp_path) as (session, trial_on_screen, failure):
        assert conftest.wait_for(trial_on_screen, 120), failure("no trial on screen")
        cpu_before, wall_before = process_cpu_s(session.pid), time.perf_counter()
        deadline = wall_before + 5.0
        while time.perf_counter() < deadline:  # CPU time, not wall time, is measured: sleeping costs nothing
            time.sleep(0.2)
        share = (process_cpu_s(session.pid) - cpu_before) / (time.perf_counter() - wall_before)
        assert share <= 0.01, f"{share:.1%} of a core while waiting for an answer"


@pytest.mark.slow
@pytest.mark.skipif(bool(tools_missing()), reason="needs Xvfb, xdotool and ImageMagick (./run tests installs them)")
def test_the_window_draws_its_trial_again_when_the_x_server_lost_it(tmp_path):
    """Xvfb keeps no copy of a hidden window: unmapped and mapped again (as a window manager does on a change of
    workspace, or as a window mapped after its first frame was drawn is), the trial must be drawn again."""
    with session_on_xvfb(tmp_path) as (session, trial_on_screen, failure):
        assert conftest.wait_for(trial_on_screen, 120), failure("no trial on screen")
        env = {**os.environ, "DISPLAY": session.display}
        found = subprocess.run(["xdotool", "search", "--sync", "--pid", str(session.pid)], env=env,
                               capture_output=True, text=True, timeout=60)  # (its title: SDL's, UTF-8 only)
        window = found.stdout.split()[0]
        subprocess.run(["xdotool", "windowunmap", "--sync", window], env=env, check=True, timeout=60)
        assert conftest.wait_for(lambda: not trial_on_screen(), 60), failure("the hidden window still on screen")
        subprocess.run(["xdotool", "windowmap", "--sync", window], env=env, check=True, timeout=60)
        assert conftest.wait_for(trial_on_screen, 60), failure("the trial was not drawn again once mapped")


@contextlib.contextmanager
def session_on_xvfb(tmp_path):
    """``experiment threshold`` in a window on a real X server (Xvfb): the session's process (``display`` set on
    it), a function telling whether a trial's zones are on the screen (as a person would see them), and one that
    words a failure with the last screenshot's result and what the session said."""
    from ultraglide.apps.experiment.window import ZONE

    xvfb, display = start_xvfb(1280, 800)
    env = {**os.environ, "DISPLAY": display}
    env.pop("SDL_VIDEODRIVER", None)
    out_path, err_path = tmp_path / "stdout.txt", tmp_path / "stderr.txt"  # files, not pipes nobody reads
    with open(out_path, "w") as out, open(err_path, "w") as err:  # while it waits (a full pipe would block it)
        session = subprocess.Popen([sys.executable, "-m", "ultraglide", "experiment", "threshold", "grating-1mm",
                                    "--method", "staircase", "--afc", "3", "--trials", "4", "--out",
                                    str(tmp_path / "s"), "--device", "null", "--windowed"], env=env, stdout=out,
                                   stderr=err)
    session.display = display
    last_shot = []  # what the screenshot said last time, for a failure's message

    def failure(what: str) -> str:
        from service_run import where_it_waits

        return (f"{what}; the last screenshot: {last_shot}; the session said "
                f"{out_path.read_text()[-1000:], err_path.read_text()[-2000:]}; where it waits:\n"
                f"{where_it_waits(session.pid)}")

    def trial_on_screen() -> bool:
        assert session.poll() is None, failure("the session ended")
        shot = subprocess.run(["import", "-window", "root", "png:-"], env=env, capture_output=True, timeout=60)
        last_shot[:] = [shot.returncode, shot.stderr[-300:]]
        if shot.returncode != 0:
            return False
        pixels = np.asarray(Image.open(io.BytesIO(shot.stdout)).convert("RGB"))
        return bool(np.all(pixels == ZONE, axis=-1).any())

    try:
        yield session, trial_on_screen, failure
    finally:
        session.kill()
        session.wait(timeout=60)
        xvfb.terminate()
        xvfb.wait(timeout=30)
