"""A participant in a browser: ``ultraglide experiment run DESIGN.toml --serve`` as a real process, its page in a
real headless Chromium (Debian's ``chromium`` and ``chromium-driver``, CDP's touch, mouse and key events through
Selenium: tests/chromium_cdp.py), or a real WebSocket client where only the lifecycle is at stake: the trial's
stimulus is felt under the synthesized finger (the engine's envelope record), and in the method of adjustment each
level set under the finger held, trials.csv holds the buttons and keys pressed with the page's reaction times and
the level an adjustment gave, a page
that closes is waited for and the session resumes or stops with its files complete, a stop signal leaves the plate
at rest and the files complete, and a bad token or origin is refused."""

import csv
import json
import math
import signal
import subprocess
import threading
import time

import numpy as np
import pytest
from chromium_cdp import chromium, click, finger_down, finger_up, needed, press_key, second_finger, tap, touch_at
from conftest import run_cli, start_cli
from service_run import read_envelope, read_line, rows_at, stop
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture
from websockets.sync.client import connect

from ultraglide.client import Client, ConnectionFailed
from ultraglide.experiment import load_design, plan

MM_PER_PX = 0.25
MEANS = {"low": 0.4, "high": 0.8}  # the stimuli's mean friction ratios, as the design asks
RATING_LABELS = ["lisse", "2", "3", "4", "rugueux"]

DESIGN = """
[experiment]
name = "browser"
seed = 3
language = "fr"
break_message = "Faites une pause."

[rig]
zone_mm = [30.0, 30.0]
gap_mm = 10.0

[stimuli.low]
texture = "low.png"
mean = 0.4

[stimuli.high]
texture = "high.png"
mean = 0.8

[[conditions]]
name = "low-vs-high"
a = "low"
b = "high"

[[conditions]]
name = "rate-low"
stimulus = "low"

[[blocks]]
name = "choice"
task = "afc"
conditions = ["low-vs-high"]
intervals = 2
repeats = 4
question = "Quelle zone était différente ?"
labels = ["gauche", "droite"]

[[blocks]]
name = "rating"
task = "rating"
conditions = ["rate-low"]
repeats = 2
scale = [1, 5]
question = "Quelle rugosité ?"
labels = ["lisse", "2", "3", "4", "rugueux"]
"""


@pytest.fixture
def design(tmp_path):
    """The design (4 trials of 2-AFC, low against high, then a rating block of 2) with its two flat textures."""
    for name in MEANS:  # flat maps: the design's mean sets each one's friction
        save_texture(Texture(np.full((20, 20), 0.6, dtype=np.float32), 20.0, 20.0, name=name), tmp_path / f"{name}.png")
    path = tmp_path / "design.toml"
    path.write_text(DESIGN, encoding="utf-8")
    return path


class Session:
    """``experiment run DESIGN --serve --json`` running: its page's address, its standard error as lines."""

    def __init__(self, design, out, *options):
        self.out = out
        self.process = start_cli("experiment", "run", design, "--participant", "P01", "--out", out, "--serve",
                                 "--port", "0", "--device", "sim", "--json", *options, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, cwd=design.parent)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        line = read_line(self.process.stdout, 180)
        assert line, f"no address printed: {self.stderr()}"
        self.address = json.loads(line)

    def _read(self):
        for line in self.process.stderr:
            self.lines.append(line)

    def stderr(self) -> str:
        return "".join(self.lines)

    def wait_said(self, words: str, timeout_s: float = 60.0) -> None:
        deadline = time.monotonic() + timeout_s
        while words not in self.stderr():
            assert time.monotonic() < deadline and self.process.poll() is None, (words, self.stderr())
            time.sleep(0.05)

    def end(self, timeout_s: float = 120.0) -> tuple[int, str]:
        status = self.process.wait(timeout_s)
        self.reader.join(30)
        return status, self.process.stdout.read()


def trials_csv(out) -> list[dict]:
    with open(out / "trials.csv", newline="", encoding="utf-8") as stream:
        return list(csv.DictReader(stream))


# ---- the page in Chromium ---------------------------------------------------------------------------------------

browser_needed = needed


@pytest.fixture
def browser(tmp_path):
    with chromium(tmp_path / "profile") as driver:
        yield driver


def screen_shown(driver, kind, trial, session, timeout_s=60.0) -> dict:
    """The page's screen once it shows ``kind`` for ``trial`` (a trial presented: its first frame drawn)."""
    deadline = time.monotonic() + timeout_s
    while True:
        screen = driver.execute_script("const p = window.participant; return p && p.screen && p.shownAt !== null "
                                       "|| (p && p.screen && p.screen.type === 'participant.break') ? p.screen : null")
        if screen and screen["type"] == kind and screen["trial"] == trial:
            return screen
        assert time.monotonic() < deadline and session.process.poll() is None, (kind, trial, screen, session.stderr())
        time.sleep(0.05)


BOXES = """return [...document.querySelectorAll(arguments[0])].map((e) => {
  const b = e.getBoundingClientRect(); return {left: b.left, top: b.top, width: b.width, height: b.height}; })"""


@browser_needed
def test_a_participant_in_chromium_feels_each_trials_stimuli_and_answers_with_its_buttons(tmp_path, design, browser):
    envelope_csv = tmp_path / "envelope.csv"
    out = tmp_path / "p01"
    trials = plan(load_design(design), "P01")  # which stimulus each zone of each trial holds
    session = Session(design, out, "--envelope-csv", envelope_csv)
    touched, pressed = [], {}
    try:
        browser.get(session.address["page"] + f"?mm_per_px={MM_PER_PX}")
        for trial in trials:
            if trial.break_before:
                screen = screen_shown(browser, "participant.break", trial.number, session)
                assert screen["message"] == "Faites une pause."
                tap(browser, browser.execute_script(BOXES, "#breakButton")[0])
            screen = screen_shown(browser, "participant.trial", trial.number, session)
            plate = browser.execute_script(BOXES, "#plate")[0]
            zones = browser.execute_script(BOXES, ".zone")
            assert len(zones) == len(trial.zones)
            for index, (zone, stimulus) in enumerate(zip(zones, trial.zones, strict=True)):
                # a point of its own in each zone of each trial (its envelope rows are this touch's alone)
                x = round(zone["left"] + zone["width"] / 2)
                y = round(zone["top"] + 10 + 4 * trial.number + 2 * index)
                touch_at(browser, x, y, 0.25)
                touched.append(((x - plate["left"]) * MM_PER_PX, (y - plate["top"]) * MM_PER_PX, MEANS[stimulus]))
            buttons = browser.execute_script(BOXES, "#answers button")
            labels = browser.execute_script("return [...document.querySelectorAll('#answers button')]"
                                            ".map((b) => b.textContent)")
            assert labels == (["gauche", "droite"] if trial.task == "afc" else RATING_LABELS)
            assert screen["question"] == ("Quelle zone était différente ?" if trial.task == "afc" else
                                          "Quelle rugosité ?")
            choice = (trial.number % 2) if trial.task == "afc" else (trial.number + 1) % 5
            pressed[trial.number] = choice
            tap(browser, buttons[choice])
            deadline = time.monotonic() + 60
            while len(browser.execute_script("return window.participant.answered")) < len(pressed):
                assert time.monotonic() < deadline, browser.execute_script("return window.participant.errors")
                time.sleep(0.05)
        sent = {a["trial"]: a for a in browser.execute_script("return window.participant.answered")}
        assert browser.execute_script("return window.participant.errors") == []
        status, stdout = session.end()
        assert browser.execute_script("return window.participant.ended")  # told the session is over
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary["complete"] is True and "Traceback" not in session.stderr()
    rows = trials_csv(out)
    assert [int(r["trial"]) for r in rows] == [t.number for t in trials]
    for row, trial in zip(rows, trials, strict=True):
        choice = pressed[trial.number]
        assert sent[trial.number]["button"] == choice
        if trial.task == "afc":
            assert int(row["response"]) == choice + 1 and row["response_label"] == ["gauche", "droite"][choice]
            assert int(row["correct"]) == int(choice == trial.target)
        else:
            assert int(row["response"]) == 1 + choice and row["response_label"] == RATING_LABELS[choice]
        rt = float(row["rt_s"])
        assert math.isfinite(rt) and 0.2 < rt < 120  # it includes the touches held before the press (0.25 s each)
        assert rt == pytest.approx(sent[trial.number]["rt_s"], abs=1e-4)  # the page's own measure, kept
    envelope = read_envelope(envelope_csv)
    for x_mm, y_mm, ratio in touched:
        under = rows_at(envelope, x_mm, y_mm)
        assert len(under) > 20, f"nothing rendered under ({x_mm}, {y_mm}) mm"
        assert np.median(under["target_ratio"]) == pytest.approx(ratio, abs=0.01)
        assert under["commanded_um_pp"].max() > 0.5  # felt: the plate played it
    assert envelope["commanded_um_pp"][-1] == 0.0  # and ended at rest


# ---- the lifecycle, through a real WebSocket client ----------------------------------------------------------------

class Page:
    """A bare WebSocket speaking as the participant's page (the page's own messages, its origin)."""

    def __init__(self, address):
        page = address["page"].split("?")[0].rstrip("/")
        self.ws = connect(address["url"], proxy=None, open_timeout=30, origin=page).__enter__()
        self.next_id = 0
        self.pushed: list[dict] = []
        assert self.ask("hello", protocol=1, client="test page")["role"] == "control"

    def ask(self, kind, **fields) -> dict:
        self.next_id += 1
        self.ws.send(json.dumps({"type": kind, "id": self.next_id, **fields}))
        while True:
            message = json.loads(self.ws.recv(timeout=60))
            if message.get("id") == self.next_id:
                return message
            self.pushed.append(message)

    def screen(self, kind, trial) -> dict:
        while True:
            while self.pushed:
                message = self.pushed.pop(0)
                if message["type"] == kind and message["trial"] == trial:
                    return message
            self.pushed.append(json.loads(self.ws.recv(timeout=60)))

    def touch(self, x, y, phase):
        self.ws.send(json.dumps({"type": "touch", "x": x, "y": y, "phase": phase}))

    def close(self):
        self.ws.close()


def test_a_page_that_closes_is_waited_for_and_the_session_resumes_when_it_is_back(tmp_path, design):
    out = tmp_path / "p01"
    session = Session(design, out, "--reconnect-timeout-s", "120")
    try:
        page = Page(session.address)
        page.screen("participant.trial", 1)
        assert page.ask("participant.answer", trial=1, button=1, rt_s=0.8)["type"] == "ok"
        shown = page.screen("participant.trial", 2)
        page.close()
        session.wait_said("the participant's page closed during trial 2: waiting up to 120 s")
        page = Page(session.address)
        again = page.screen("participant.trial", 2)  # shown again, as it was
        assert again == shown
        session.wait_said("the participant's page is back: trial 2 shown again")
        refused = page.ask("participant.answer", trial=1, button=0, rt_s=0.5)  # a stale answer
        assert refused["type"] == "error" and "trial 1 is not the one awaiting an answer" in refused["message"]
        refused = page.ask("participant.answer", trial=2, button=2, rt_s=0.5)  # no third button
        assert refused["type"] == "error" and "from 0 to 1" in refused["message"]
        refused = page.ask("sprite.set", sprite="s", texture="t", x=0, y=0, width=1, height=1)
        assert refused["type"] == "error" and refused["code"] == "read-only"
        assert page.ask("participant.answer", trial=2, button=0, rt_s=2.5)["type"] == "ok"
        for number in (3, 4):
            page.screen("participant.trial", number)
            assert page.ask("participant.answer", trial=number, button=0, rt_s=0.5 + number)["type"] == "ok"
        page.screen("participant.break", 5)
        assert page.ask("participant.continue", trial=5)["type"] == "ok"
        for number in (5, 6):
            screen = page.screen("participant.trial", number)
            assert screen["mode"] == "rating" and screen["labels"] == RATING_LABELS
            assert page.ask("participant.answer", trial=number, button=4, rt_s=1.25)["type"] == "ok"
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    rows = trials_csv(out)
    assert [r["response"] for r in rows] == ["2", "1", "1", "1", "5", "5"]
    assert [float(r["rt_s"]) for r in rows] == [0.8, 2.5, 3.5, 4.5, 1.25, 1.25]
    assert json.loads((out / "session.json").read_text())["status"] == "complete"


def test_a_page_gone_past_the_timeout_stops_the_session_with_its_files_complete(tmp_path, design):
    out = tmp_path / "p01"
    session = Session(design, out, "--reconnect-timeout-s", "1")
    try:
        page = Page(session.address)
        page.screen("participant.trial", 1)
        assert page.ask("participant.answer", trial=1, button=0, rt_s=0.6)["type"] == "ok"
        page.screen("participant.trial", 2)
        page.close()
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 1, session.stderr()
    assert "stayed away more than 1 s: the session stops at trial 2, its files complete" in session.stderr()
    assert "Traceback" not in session.stderr()
    assert json.loads(stdout.strip().splitlines()[-1])["complete"] is False
    assert [r["trial"] for r in trials_csv(out)] == ["1"]
    saved = json.loads((out / "session.json").read_text())
    assert saved["status"] == "stopped" and saved["trials_logged"] == 1
    assert json.loads((out / "summary.json").read_text())["complete"] is False


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_mid_trial_leaves_the_plate_at_rest_and_the_files_complete(tmp_path, design, signum):
    out = tmp_path / "p01"
    envelope_csv = tmp_path / "envelope.csv"
    session = Session(design, out, "--envelope-csv", envelope_csv)
    try:
        page = Page(session.address)
        page.screen("participant.trial", 1)
        assert page.ask("participant.answer", trial=1, button=1, rt_s=0.7)["type"] == "ok"
        page.screen("participant.trial", 2)
        page.touch(20.0, 25.0, "down")  # a finger down in the first zone when the stop comes
        for _ in range(30):
            time.sleep(0.01)
            page.touch(20.0, 25.0, "move")
        session.process.send_signal(signum)
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 128 + signum, session.stderr()
    assert "Traceback" not in session.stderr()
    assert "stopped after 1 trial; the log is in" in session.stderr()
    assert [r["trial"] for r in trials_csv(out)] == ["1"]
    assert json.loads((out / "session.json").read_text())["status"] == "stopped"
    envelope = read_envelope(envelope_csv)
    assert rows_at(envelope, 20.0, 25.0)["commanded_um_pp"].max() > 0.5  # the finger felt trial 2's zone
    assert envelope["commanded_um_pp"][-1] == 0.0  # and the plate ended at rest


def test_the_words_at_the_start_say_what_stops_the_session_and_esc_on_the_page_does(tmp_path, design):
    """Without --json the command says how the session stops: Esc on the page, or Ctrl-C at the command (the test
    above), each with the files complete and the plate at rest, and --resume going on. Esc is pressed here."""
    out, envelope_csv = tmp_path / "p01", tmp_path / "envelope.csv"
    process = start_cli("experiment", "run", design, "--participant", "P01", "--out", out, "--serve", "--port", "0",
                        "--device", "sim", "--envelope-csv", envelope_csv, stdout=subprocess.PIPE,
                        stderr=subprocess.PIPE, cwd=design.parent)
    lines: list[str] = []  # the standard output, read as it comes (both lines may arrive in one read)

    def read():
        for line in process.stdout:
            lines.append(line)

    threading.Thread(target=read, daemon=True).start()
    try:
        deadline = time.monotonic() + 180
        while len(lines) < 2:
            assert time.monotonic() < deadline and process.poll() is None, lines
            time.sleep(0.05)
        page_url, url = lines[0].split()
        said = lines[1].rstrip("\n")
        assert said.startswith(f"the participant's page: open {page_url} on their screen"), said
        assert said.endswith("; Esc on the page or Ctrl-C here stops the session, its files complete and the plate "
                             "at rest (--resume goes on)"), said
        page = Page({"page": page_url, "url": url})
        page.screen("participant.trial", 1)
        assert page.ask("participant.answer", trial=1, button=1, rt_s=0.6)["type"] == "ok"
        page.screen("participant.trial", 2)
        assert page.ask("participant.stop", trial=2)["type"] == "ok"  # Esc on the page
        status = process.wait(120)
        err = process.stderr.read()
    finally:
        stop(process)
    assert status == 1 and "the participant pressed Esc during trial 2" in err and "Traceback" not in err, err
    assert json.loads((out / "session.json").read_text())["status"] == "stopped"
    assert [r["trial"] for r in trials_csv(out)] == ["1"]
    assert read_envelope(envelope_csv)["commanded_um_pp"][-1] == 0.0  # the plate at rest
    resumed = Session(design, out, "--resume")  # and --resume goes on from trial 2
    try:
        Page(resumed.address).screen("participant.trial", 2)
    finally:
        stop(resumed.process)


def test_a_bad_token_and_another_origin_are_refused(tmp_path, design):
    session = Session(design, tmp_path / "p01", "--token", "a-secret-token-1")
    try:
        address = session.address
        assert address["token"] == "a-secret-token-1" and "token=a-secret-token-1" in address["page"]
        bare = address["url"].split("?")[0]
        with pytest.raises(ConnectionFailed, match="401"):
            Client(bare)
        with pytest.raises(ConnectionFailed, match="401"):
            Client(bare + "?token=a-secret-token-2")
        with pytest.raises(ConnectionFailed, match="403"):
            Client(address["url"], origin="http://evil.example")
        page = Page(address)  # the token and the served page's origin: the participant
        assert page.screen("participant.trial", 1)["labels"] == ["gauche", "droite"]
        page.close()
    finally:
        status = stop(session.process)
    assert status == 128 + signal.SIGTERM
    assert json.loads((tmp_path / "p01" / "session.json").read_text())["status"] == "stopped"


def test_beyond_the_usual_loopback_a_token_is_made_printed_and_required(tmp_path, design):
    session = Session(design, tmp_path / "p01", "--host", "127.0.0.2")
    try:
        address = session.address
        token = address["token"]
        assert token and len(token) >= 20 and f"?token={token}" in address["page"] and "127.0.0.2" in address["page"]
        with pytest.raises(ConnectionFailed, match="401"):
            Client(address["url"].split("?")[0])
        page = Page(address)
        assert page.screen("participant.trial", 1)["trial"] == 1
        page.close()
    finally:
        stop(session.process)


@pytest.mark.parametrize(("options", "words"), [
    (["--serve", "--observer", "sim:threshold=0.1"], "--serve is for the participant's window or page"),
    (["--host", "0.0.0.0"], "--host is for the participant's page: add --serve"),
    (["--envelope-csv", "e.csv"], "--envelope-csv is for the participant's page: add --serve"),
    (["--serve", "--windowed"], "--windowed is for the window"),
    (["--serve", "--token", "short"], "a token is 8 to 200 letters"),
])
def test_options_of_another_way_of_running_are_refused_in_one_line(tmp_path, design, options, words):
    result = run_cli("experiment", "run", design, "--participant", "P01", "--out", tmp_path / "o", *options,
                     cwd=design.parent)
    assert result.returncode == 2 and words in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) <= 2  # argparse's usage line may come first
    assert not (tmp_path / "o").exists()


ADJUST_DESIGN = DESIGN.split("[[conditions]]")[0] + """
[stimuli.patch]
texture = "patch.png"

[[conditions]]
name = "low-vs-high"
a = "low"
b = "high"

[[conditions]]
name = "rate-low"
stimulus = "low"

[[conditions]]
name = "match"
stimulus = "patch"
reference = "high"
range = [0.05, 0.6]

[[blocks]]
name = "choice"
task = "afc"
conditions = ["low-vs-high"]
intervals = 2
repeats = 2

[[blocks]]
name = "rating"
task = "rating"
conditions = ["rate-low"]
repeats = 1
scale = [1, 5]

[[blocks]]
name = "matching"
task = "adjustment"
conditions = ["match"]
repeats = 1
question = "Rendez la zone 2 pareille à la zone 1."
labels = ["moins", "plus", "OK"]
"""
STEP = 10 ** (1 / 20)  # the window's step of an adjustment: 1 dB of contrast


def adjusted_level(driver, wanted, session, timeout_s=60.0) -> float:
    """The page's level once the plate plays it (the service answered its last adjust request), approx ``wanted``."""
    deadline = time.monotonic() + timeout_s
    while True:
        level, applied = driver.execute_script("return [window.participant.level, window.participant.applied]")
        if level == applied and level == pytest.approx(wanted, rel=1e-9):
            return level
        assert time.monotonic() < deadline and session.process.poll() is None, (
            level, applied, wanted, driver.execute_script("return window.participant.errors"), session.stderr())
        time.sleep(0.02)


def answered(driver, count, timeout_s=60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while len(driver.execute_script("return window.participant.answered")) < count:
        assert time.monotonic() < deadline, driver.execute_script("return window.participant.errors")
        time.sleep(0.05)


@browser_needed
def test_an_adjustment_set_by_keys_buttons_and_slider_is_felt_live_and_logged_and_keys_answer(tmp_path, design,
                                                                                               browser):
    """The method of adjustment on the page: a finger held on the adjusted zone while keys, the + button (a mouse
    click), the − button and the slider (a second finger's tap and drag) set its contrast; each level is felt under
    the finger (the envelope record: the patch texture's ratio, 1 - contrast, as zone_texture maps it), and
    trials.csv holds the level given with Enter, as the window records it. The 2-AFC and rating trials before it
    are answered by keys alone."""
    values = np.full((20, 20), 0.3, dtype=np.float32)
    values[:2, :2] = 0.9  # a bright corner: the rest of the zone is the texture's minimum, ratio 1 - contrast
    save_texture(Texture(values, 20.0, 20.0, name="patch"), tmp_path / "patch.png")
    design.write_text(ADJUST_DESIGN, encoding="utf-8")
    trials = plan(load_design(design), "P01")
    assert [t.task for t in trials] == ["afc", "afc", "rating", "adjustment"]
    low, high = 0.05, 0.6
    start = trials[3].level
    assert low <= start <= high
    envelope_csv = tmp_path / "envelope.csv"
    out = tmp_path / "p01"
    session = Session(design, out, "--envelope-csv", envelope_csv, "--accept-check")
    keys = {1: "2", 2: "ArrowLeft", 3: "4"}
    try:
        browser.get(session.address["page"] + f"?mm_per_px={MM_PER_PX}")
        for trial in trials[:3]:
            if trial.break_before:
                screen_shown(browser, "participant.break", trial.number, session)
                press_key(browser, " ")
            screen = screen_shown(browser, "participant.trial", trial.number, session)
            hint = browser.execute_script("return document.getElementById('keys').textContent")
            assert hint == ("Keys: 1–2 (or ← / →) answer. Esc stops the session." if trial.task == "afc" else
                            "Keys: 1–5 for the scale's points, from its low end. Esc stops the session.")
            press_key(browser, "7")  # no such answer: nothing happens
            press_key(browser, keys[trial.number])
            answered(browser, trial.number)
        if trials[3].break_before:
            screen_shown(browser, "participant.break", 4, session)
            press_key(browser, "Enter")
        screen = screen_shown(browser, "participant.trial", 4, session)
        assert screen["mode"] == "adjustment" and screen["labels"] == ["moins", "plus", "OK"]
        assert screen["level"] == start and screen["range"] == [low, high] and screen["step_db"] == 1.0
        assert browser.execute_script("return document.getElementById('keys').textContent") == (
            "Keys: ← or − down, → or + up (1 dB a step), Enter gives it. Esc stops the session.")
        plate = browser.execute_script(BOXES, "#plate")[0]
        zone = browser.execute_script(BOXES, ".zone")[1]  # the adjusted zone, the second
        x, y = round(zone["left"] + zone["width"] / 2), round(zone["top"] + zone["height"] / 2)
        at_mm = ((x - plate["left"]) * MM_PER_PX, (y - plate["top"]) * MM_PER_PX)
        labels = browser.execute_script("return [...document.querySelectorAll('#answers button')]"
                                        ".map((b) => b.textContent)")
        buttons = dict(zip(labels, browser.execute_script(BOXES, "#answers button"), strict=True))
        slider = browser.execute_script(BOXES, "#level")[0]
        clamp = lambda level: min(max(level, low), high)  # noqa: E731
        levels = [start]
        finger_down(browser, x, y)  # held on the adjusted zone throughout
        held_since = time.monotonic()

        def hold(seconds=0.4):  # each level felt for a while (the finger still down)
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                time.sleep(0.02)

        hold()
        press_key(browser, "ArrowRight")  # a key: 1 dB up
        levels.append(adjusted_level(browser, clamp(levels[-1] * STEP), session))
        hold()
        plus = buttons["plus"]
        click(browser, plus["left"] + plus["width"] / 2, plus["top"] + plus["height"] / 2)  # the + button: 1 dB up
        levels.append(adjusted_level(browser, clamp(levels[-1] * STEP), session))
        hold()
        minus = buttons["moins"]
        second_finger(browser, (x, y), [(minus["left"] + minus["width"] / 2, minus["top"] + minus["height"] / 2)])
        levels.append(adjusted_level(browser, clamp(levels[-1] / STEP), session))  # a tap on −: 1 dB down
        hold()
        thumb = browser.execute_script(BOXES, "#level .thumb")[0]
        thumb_x, middle = thumb["left"] + thumb["width"] / 2, thumb["top"] + thumb["height"] / 2
        path = [(thumb_x + (slider["left"] + slider["width"] + 30 - thumb_x) * i / 10, middle) for i in range(11)]
        second_finger(browser, (x, y), path)  # the slider's thumb dragged past its end: the range's top
        levels.append(adjusted_level(browser, high, session))
        hold()
        press_key(browser, "-")  # 1 dB down
        levels.append(adjusted_level(browser, clamp(levels[-1] / STEP), session))
        hold()
        finger_up(browser)
        held_s = time.monotonic() - held_since
        press_key(browser, "Enter")  # gives the level set
        answered(browser, 4)
        assert browser.execute_script("return window.participant.errors") == []
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    rows = trials_csv(out)
    assert [int(r["response"]) for r in rows[:2]] == [2, 1]  # "2", then ← (the first interval)
    assert rows[2]["response"] == "4" and rows[2]["response_label"] == "4"
    adjustment = rows[3]
    assert float(adjustment["level"]) == start  # the adjustment's start, as the window logs it
    assert float(adjustment["response"]) == levels[-1]  # the level given
    assert levels[-1] == pytest.approx(high / STEP, rel=1e-9)
    assert adjustment["response_label"] == f"{levels[-1]:.4g}"
    assert 0 < float(adjustment["rt_s"]) and float(adjustment["rt_s"]) > held_s - 0.5
    # the friction under the held finger followed every level, in order: 1 - contrast on the patch's minimum
    under = rows_at(read_envelope(envelope_csv), *at_mm, within_mm=0.2)
    assert len(under) > 100, f"nothing rendered under {at_mm} mm"
    ratios = under["target_ratio"][np.argsort(under["t_s"], kind="stable")]
    starts = np.flatnonzero(np.r_[True, np.abs(np.diff(ratios)) > 1e-4])  # runs of one ratio, in time order
    runs = [(ratios[a], b - a) for a, b in zip(starts, [*starts[1:], len(ratios)], strict=True)]
    felt = []
    for ratio, count in runs:
        if count >= 20 and (not felt or abs(felt[-1] - ratio) > 1e-4):  # a level held, not a passing row
            felt.append(float(ratio))
    wanted = [1.0 - level for level in levels]
    assert felt[:4] == pytest.approx(wanted[:4], abs=0.005), (levels, runs)
    assert felt[-2:] == pytest.approx(wanted[-2:], abs=0.005), (levels, runs)
    passed = felt[4:-2]  # the levels the slider passed through on its way to the top, each lower in friction
    assert passed == sorted(passed, reverse=True) and all(wanted[4] < r < wanted[3] for r in passed), (levels, runs)
    assert under["commanded_um_pp"].max() > 0.5  # felt: the plate played it


def test_an_adjustment_s_levels_are_checked_and_a_page_that_comes_back_shows_the_level_set(tmp_path, design):
    values = np.full((20, 20), 0.3, dtype=np.float32)
    values[:2, :2] = 0.9
    save_texture(Texture(values, 20.0, 20.0, name="patch"), tmp_path / "patch.png")
    design.write_text(ADJUST_DESIGN.replace("repeats = 2\n", "repeats = 1\n"), encoding="utf-8")
    out = tmp_path / "p01"
    session = Session(design, out, "--accept-check", "--reconnect-timeout-s", "120")
    try:
        page = Page(session.address)
        page.screen("participant.trial", 1)  # 2-AFC: no level to set
        refused = page.ask("participant.adjust", trial=1, level=0.2)
        assert refused["type"] == "error" and "trial 1 is not an adjustment awaiting its answer" in refused["message"]
        assert page.ask("participant.answer", trial=1, button=0, rt_s=0.5)["type"] == "ok"
        for number in (2, 3):  # a break before each new block
            page.screen("participant.break", number)
            assert page.ask("participant.continue", trial=number)["type"] == "ok"
            if number == 2:
                page.screen("participant.trial", 2)
                assert page.ask("participant.answer", trial=2, button=2, rt_s=0.5)["type"] == "ok"
        shown = page.screen("participant.trial", 3)
        assert shown["mode"] == "adjustment" and shown["range"] == [0.05, 0.6]
        for level in (0.01, 0.61):
            refused = page.ask("participant.adjust", trial=3, level=level)
            assert refused["type"] == "error" and "'level' must be from 0.05 to 0.6" in refused["message"]
        played = page.ask("participant.adjust", trial=3, level=0.25)
        assert played["type"] == "ok" and played["level"] == 0.25  # answered once the engine plays it
        refused = page.ask("participant.answer", trial=3, value=0.3, rt_s=1.0)  # not the level set
        assert refused["type"] == "error" and "the level set last (0.25)" in refused["message"]
        page.close()
        session.wait_said("the participant's page closed during trial 3")
        page = Page(session.address)
        again = page.screen("participant.trial", 3)
        assert again == {**shown, "level": 0.25}  # shown again at the level the plate plays
        assert page.ask("participant.answer", trial=3, value=0.25, rt_s=2.0)["type"] == "ok"
        status, _ = session.end()
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    rows = trials_csv(out)
    assert rows[2]["task"] == "adjustment" and float(rows[2]["response"]) == 0.25
    assert rows[2]["response_label"] == "0.25" and float(rows[2]["level"]) == shown["level"]


def test_a_python_script_runs_a_design_with_the_browser_responder(tmp_path, design):
    from ultraglide.apps.experiment.browser import BrowserResponder

    from ultraglide.experiment import run

    loaded = load_design(design)
    said: list[str] = []
    answers = {1: 1, 2: 0, 3: 1, 4: 0, 5: 2, 6: 3}

    def participant(address):
        page = Page(address)
        for number, button in answers.items():
            if number == 5:
                page.screen("participant.break", 5)
                page.ask("participant.continue", trial=5)
            page.screen("participant.trial", number)
            assert page.ask("participant.answer", trial=number, button=button, rt_s=0.25 * number)["type"] == "ok"
        page.close()

    import os

    here = os.getcwd()
    os.chdir(design.parent)  # the design's textures are named relative to it
    try:
        with BrowserResponder(loaded, device="null", port=0, say=said.append) as page:
            assert page.page_url.startswith("http://127.0.0.1:") and page.token is None
            answering = threading.Thread(target=participant, args=({"url": page.url, "page": page.page_url},))
            answering.start()
            session = run(loaded, "P01", out=tmp_path / "api", responder=page)
            answering.join(60)
    finally:
        os.chdir(here)
    assert session.complete and page.stopped is None
    assert [row["response"] for row in session.trials] == [2, 1, 2, 1, 3, 4]  # 2-AFC intervals from 1; ratings from 1
    assert [row["rt_s"] for row in session.trials] == [0.25, 0.5, 0.75, 1.0, 1.25, 1.5]
    assert said and said[0].startswith("waiting for the participant's page: open http://127.0.0.1:")


SECOND_DESIGN = DESIGN.split("[[blocks]]")[0].replace("[[conditions]]", """[stimuli.grating]
texture = "grating-2mm"

[[conditions]]
name = "detect"
stimulus = "grating"
levels = [0.1, 0.5]

[[conditions]]""", 1) + """
[[blocks]]
name = "pairs"
task = "same_different"
conditions = ["low-vs-high"]
repeats = 1
question = "Pareilles ou différentes ?"
labels = ["pareilles", "différentes"]

[[blocks]]
name = "estimate"
task = "magnitude"
conditions = ["rate-low"]
repeats = 2
modulus = 10.0
modulus_stimulus = "high"
question = "Combien ?"

[[blocks]]
name = "detection"
task = "constant"
conditions = ["detect"]
intervals = 1
repeats = 1
labels = ["oui", "non"]
"""


@browser_needed
def test_same_different_buttons_and_keys_and_a_typed_magnitude_estimate_reach_trials_csv(tmp_path, design, browser):
    design.write_text(SECOND_DESIGN, encoding="utf-8")
    out = tmp_path / "p01"
    trials = plan(load_design(design), "P01")
    assert [t.task for t in trials] == ["same_different"] * 4 + ["magnitude"] * 2 + ["constant"] * 2
    session = Session(design, out, "--accept-check")
    typed = {5: "12.5"}
    try:
        browser.get(session.address["page"] + f"?mm_per_px={MM_PER_PX}")
        for trial in trials:
            if trial.break_before:
                screen_shown(browser, "participant.break", trial.number, session)
                tap(browser, browser.execute_script(BOXES, "#breakButton")[0])
            screen = screen_shown(browser, "participant.trial", trial.number, session)
            if trial.task == "same_different":
                assert screen["mode"] == "pair" and screen["labels"] == ["pareilles", "différentes"]
                assert browser.execute_script("return document.getElementById('keys').textContent") == (
                    "Keys: S for same, D for different. Esc stops the session.")
                if trial.number <= 2:  # trials 1 and 3 "différentes", 2 and 4 "pareilles": buttons, then keys
                    tap(browser, browser.execute_script(BOXES, "#answers button")[trial.number % 2])
                else:
                    press_key(browser, "d" if trial.number == 3 else "s")
            elif trial.task == "constant":  # yes/no: Y, then N
                assert screen["mode"] == "yes_no" and screen["labels"] == ["oui", "non"]
                assert browser.execute_script("return document.getElementById('keys').textContent") == (
                    "Keys: Y for yes, N for no. Esc stops the session.")
                press_key(browser, "y" if trial.number == 7 else "n")
            elif trial.number == 6:  # typed with the keys, the field never touched
                for key in ("3", "Backspace", "4", ".", "5", "Enter"):
                    press_key(browser, key)
            else:
                assert screen["mode"] == "magnitude" and screen["question"] == "Combien ? (zone 1 = 10)"
                assert browser.execute_script("return [...document.querySelectorAll('.zone')]"
                                              ".map((z) => z.textContent)") == ["1", "2"]
                field = browser.execute_script(BOXES, "#estimate")[0]
                tap(browser, field)
                browser.execute_cdp_cmd("Input.insertText", {"text": typed[trial.number]})
                browser.execute_cdp_cmd("Input.dispatchKeyEvent", {"type": "keyDown", "key": "Enter", "code": "Enter",
                                                                   "windowsVirtualKeyCode": 13})
                browser.execute_cdp_cmd("Input.dispatchKeyEvent", {"type": "keyUp", "key": "Enter", "code": "Enter",
                                                                   "windowsVirtualKeyCode": 13})
            deadline = time.monotonic() + 60
            while len(browser.execute_script("return window.participant.answered")) < trial.number:
                assert time.monotonic() < deadline, browser.execute_script("return window.participant.errors")
                time.sleep(0.05)
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    rows = trials_csv(out)
    assert [r["response"] for r in rows[:4]] == ["different", "same", "different", "same"]
    assert [r["response_label"] for r in rows[:4]] == ["différentes", "pareilles", "différentes", "pareilles"]
    for row, trial in zip(rows[:4], trials[:4], strict=True):
        assert int(row["correct"]) == int((trial.number % 2 == 1) == bool(trial.target))
    assert [float(r["response"]) for r in rows[4:6]] == [12.5, 4.5]
    assert [r["response"] for r in rows[6:]] == ["yes", "no"] and [r["response_label"] for r in rows[6:]] == [
        "oui", "non"]
    assert all(math.isfinite(float(r["rt_s"])) and float(r["rt_s"]) > 0 for r in rows)


def test_an_engine_lost_mid_trial_ends_the_session_with_engine_lost_and_keeps_the_trials_logged(tmp_path, design):
    import os

    from ultraglide.apps.experiment.browser import BrowserResponder
    from ultraglide.render.engine import EngineLost

    from ultraglide.experiment import run

    loaded = load_design(design)
    here = os.getcwd()
    os.chdir(design.parent)
    try:
        with BrowserResponder(loaded, device="null", port=0, say=lambda line: None) as page:
            def participant():
                client = Page({"url": page.url, "page": page.page_url})
                client.screen("participant.trial", 1)
                client.ask("participant.answer", trial=1, button=0, rt_s=0.4)
                client.screen("participant.trial", 2)
                os.kill(page.engine.process.pid, signal.SIGKILL)  # the engine dies while trial 2 waits

            answering = threading.Thread(target=participant, daemon=True)
            answering.start()
            with pytest.raises(EngineLost) as lost:
                run(loaded, "P01", out=tmp_path / "lost", responder=page)
            answering.join(60)
    finally:
        os.chdir(here)
    assert "its process was killed by SIGKILL" in str(lost.value)
    assert [r["trial"] for r in trials_csv(tmp_path / "lost")] == ["1"]  # the trial answered before, on disk


# ---- Esc, and the page's words in the design's language ------------------------------------------------------------

FRENCH_DESIGN = DESIGN.split("[[blocks]]")[0] + """
[[blocks]]
name = "choice"
task = "afc"
conditions = ["low-vs-high"]
intervals = 2
repeats = 2
question = "Quelle zone était différente ?"
labels = ["gauche", "droite"]

[[blocks]]
name = "estimate"
task = "magnitude"
conditions = ["rate-low"]
repeats = 2
modulus = 10.0
modulus_stimulus = "high"
question = "Combien ?"

[words]
progress = "Essai {trial} sur {total}"
keys_choice = "Touches : 1–{last} (ou ← / →) pour répondre."
keys_magnitude = "Touches : tapez le nombre, Entrée le donne."
keys_break = "Espace ou Entrée pour continuer."
keys_stop = "Échap arrête la séance."
ok = "Valider"
modulus = "(la zone 1 vaut {modulus})"
end = "La séance est terminée. Merci !"
connection_lost = "Connexion perdue ; nouvelle tentative."
"""


def press_escape(driver):
    for kind in ("rawKeyDown", "keyUp"):
        driver.execute_cdp_cmd("Input.dispatchKeyEvent", {"type": kind, "key": "Escape", "code": "Escape",
                                                          "windowsVirtualKeyCode": 27})


def page_text(driver, selector) -> str:
    return driver.execute_script("return document.querySelector(arguments[0]).textContent", selector)


@browser_needed
def test_a_french_design_s_words_are_the_page_s_and_esc_in_the_estimate_field_stops_the_session(tmp_path, design,
                                                                                                browser):
    """Every word the participant reads on the page is the design's (its blocks' questions and labels, its [words]);
    Esc, pressed while the number field has the focus, stops the session as at the window: the trial gets no answer,
    the trials answered stay logged, session.json says stopped, the command exits 1 and says so, the page says the
    design's end and the plate is at rest."""
    design.write_text(FRENCH_DESIGN, encoding="utf-8")
    trials = plan(load_design(design), "P01")
    assert [t.task for t in trials] == ["afc", "afc", "magnitude", "magnitude"] and trials[2].break_before
    out = tmp_path / "p01"
    envelope_csv = tmp_path / "envelope.csv"
    session = Session(design, out, "--accept-check", "--envelope-csv", envelope_csv)
    try:
        browser.get(session.address["page"] + f"?mm_per_px={MM_PER_PX}")
        for number, key in ((1, "1"), (2, "ArrowRight")):
            screen_shown(browser, "participant.trial", number, session)
            assert page_text(browser, "#progress") == f"Essai {number} sur 4"
            assert browser.execute_script("return document.documentElement.lang") == "fr"  # the design's language
            assert page_text(browser, "#question") == "Quelle zone était différente ?"
            assert page_text(browser, "#keys") == ("Touches : 1–2 (ou ← / →) pour répondre. Échap arrête la "
                                                   "séance.")
            press_key(browser, key)
            answered(browser, number)
        screen_shown(browser, "participant.break", 3, session)
        assert page_text(browser, "#breakMessage") == "Faites une pause."
        assert page_text(browser, "#breakButton") == "Valider"
        assert page_text(browser, "#breakKeys") == "Espace ou Entrée pour continuer. Échap arrête la séance."
        press_key(browser, " ")
        screen_shown(browser, "participant.trial", 3, session)
        assert page_text(browser, "#progress") == "Essai 3 sur 4"
        assert page_text(browser, "#question") == "Combien ? (la zone 1 vaut 10)"
        assert page_text(browser, "#answers button") == "Valider"
        assert page_text(browser, "#keys") == "Touches : tapez le nombre, Entrée le donne. Échap arrête la séance."
        tap(browser, browser.execute_script(BOXES, "#estimate")[0])  # the focus in the field, a number typed
        browser.execute_cdp_cmd("Input.insertText", {"text": "7"})
        assert browser.execute_script("return document.activeElement.id") == "estimate"
        press_escape(browser)
        status, stdout = session.end()
        deadline = time.monotonic() + 30
        while not browser.execute_script("return window.participant.ended"):
            assert time.monotonic() < deadline, browser.execute_script("return window.participant.errors")
            time.sleep(0.05)
        assert page_text(browser, "#question") == "La séance est terminée. Merci !"
        assert browser.execute_script("return window.participant.stopped") == 3
        assert browser.execute_script("return window.participant.errors") == []
    finally:
        stop(session.process)
    assert status == 1, session.stderr()
    assert "the participant pressed Esc during trial 3: the session stops, its files complete" in session.stderr()
    assert "Traceback" not in session.stderr()
    assert json.loads(stdout.strip().splitlines()[-1])["complete"] is False
    assert [(r["trial"], r["response"]) for r in trials_csv(out)] == [("1", "1"), ("2", "2")]
    saved = json.loads((out / "session.json").read_text())
    assert saved["status"] == "stopped" and saved["trials_logged"] == 2
    assert read_envelope(envelope_csv)["commanded_um_pp"][-1] == 0.0  # the plate at rest


@browser_needed
def test_a_lost_connection_is_said_in_the_designs_words(tmp_path, design, browser):
    """The service gone (killed) while a trial is shown: the page, reconnecting, says so in the design's words."""
    design.write_text(FRENCH_DESIGN, encoding="utf-8")
    session = Session(design, tmp_path / "p01", "--accept-check")
    try:
        browser.get(session.address["page"] + f"?mm_per_px={MM_PER_PX}")
        screen_shown(browser, "participant.trial", 1, session)
        assert page_text(browser, "#note") == ""
        session.process.kill()
        session.process.wait(60)
        deadline = time.monotonic() + 30
        while page_text(browser, "#note") != "Connexion perdue ; nouvelle tentative.":
            assert time.monotonic() < deadline, page_text(browser, "#note")
            time.sleep(0.05)
    finally:
        stop(session.process)


def test_esc_at_a_break_stops_the_session_and_resume_continues_it_with_english_words_by_default(tmp_path, design):
    out = tmp_path / "p01"
    session = Session(design, out)
    try:
        page = Page(session.address)
        screen = page.screen("participant.trial", 1)
        assert screen["progress"] == "Trial 1 of 6"  # no [words]: English
        assert screen["keys"] == "Keys: 1–2 (or ← / →) answer. Esc stops the session."
        refused = page.ask("participant.stop", trial=2)  # not the trial shown
        assert refused["type"] == "error" and "trial 2 (or the break before it) is not shown now" in refused["message"]
        for number in range(1, 5):
            if number > 1:
                page.screen("participant.trial", number)
            assert page.ask("participant.answer", trial=number, button=number % 2, rt_s=0.5)["type"] == "ok"
        pause = page.screen("participant.break", 5)
        assert pause["label"] == "OK" and pause["keys"] == "Space or Enter goes on. Esc stops the session."
        assert page.ask("participant.stop", trial=5)["type"] == "ok"
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 1, session.stderr()
    assert "the participant pressed Esc during the break before trial 5" in session.stderr()
    assert json.loads(stdout.strip().splitlines()[-1])["complete"] is False
    assert json.loads((out / "session.json").read_text())["status"] == "stopped"
    assert len(trials_csv(out)) == 4
    session = Session(design, out, "--resume")  # goes on from the break before trial 5
    try:
        page = Page(session.address)
        page.screen("participant.break", 5)
        assert page.ask("participant.continue", trial=5)["type"] == "ok"
        for number in (5, 6):
            page.screen("participant.trial", number)
            assert page.ask("participant.answer", trial=number, button=2, rt_s=0.5)["type"] == "ok"
        end = None
        while end is None:
            message = json.loads(page.ws.recv(timeout=60))
            end = message if message["type"] == "participant.end" else None
        status, _ = session.end()
    finally:
        stop(session.process)
    assert status == 0, session.stderr()
    assert end["message"] == "The session is over. Thank you."
    assert [r["trial"] for r in trials_csv(out)] == ["1", "2", "3", "4", "5", "6"]
    assert json.loads((out / "session.json").read_text())["status"] == "complete"


def test_esc_while_an_adjusted_level_is_on_its_way_stops_the_session_after_that_level_plays(tmp_path, design):
    values = np.full((20, 20), 0.3, dtype=np.float32)
    values[:2, :2] = 0.9
    save_texture(Texture(values, 20.0, 20.0, name="patch"), tmp_path / "patch.png")
    design.write_text(ADJUST_DESIGN.replace("repeats = 2\n", "repeats = 1\n"), encoding="utf-8")
    out = tmp_path / "p01"
    session = Session(design, out, "--accept-check")
    try:
        page = Page(session.address)
        page.screen("participant.trial", 1)
        assert page.ask("participant.answer", trial=1, button=0, rt_s=0.5)["type"] == "ok"
        for number in (2, 3):
            page.screen("participant.break", number)
            assert page.ask("participant.continue", trial=number)["type"] == "ok"
            if number == 2:
                page.screen("participant.trial", 2)
                assert page.ask("participant.answer", trial=2, button=2, rt_s=0.5)["type"] == "ok"
        page.screen("participant.trial", 3)
        page.next_id += 1
        page.ws.send(json.dumps({"type": "participant.adjust", "id": page.next_id, "trial": 3, "level": 0.3}))
        adjusted = page.next_id  # not waited for: Esc comes before its answer
        stopped = page.ask("participant.stop", trial=3)
        assert stopped["type"] == "ok" and stopped["trial"] == 3
        replies = {m["id"]: m for m in page.pushed if "id" in m}
        while adjusted not in replies:
            message = json.loads(page.ws.recv(timeout=60))
            replies[message.get("id")] = message
        assert replies[adjusted]["type"] == "ok" and replies[adjusted]["level"] == 0.3  # played, then the stop
        status, stdout = session.end()
    finally:
        stop(session.process)
    assert status == 1, session.stderr()
    assert "the participant pressed Esc during trial 3" in session.stderr() and "Traceback" not in session.stderr()
    assert [r["trial"] for r in trials_csv(out)] == ["1", "2"]
    assert json.loads((out / "session.json").read_text())["status"] == "stopped"
