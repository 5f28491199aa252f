"""Whole sessions: the command, its files read back, threshold recovery, resuming, stimuli as rendered."""

import csv
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from PIL import Image
from ultraglide.apps.commands.experiment import design_for
from ultraglide.apps.experiment.session import SessionConfig, run_session
from ultraglide.devices.profiles import load_profile
from ultraglide.render.physics.friction_models import ExponentialModel
from ultraglide.textures.library import resolve_texture
from ultraglide.textures.sampling import Sampler

from ultraglide.experiment.dryrun import SimResponder, TrialCache
from ultraglide.experiment.observer import SimObserver
from ultraglide.experiment.stimuli import Layout, StimulusDesign, render_offline, with_contrast

SIM = "sim:threshold=0.08,slope=3,lapse=0.02"


def dry_run(tmp_path, figures=True, shared=None, **options):
    """A dry session. ``shared``: a dict its sessions keep their design and trial textures in (sessions that
    differ only by seed, method and trial count share them: the same stimuli at the same levels)."""
    config = SessionConfig(**{"texture": "grating-1mm", "observer": SIM, "bootstrap": 200, **options})
    if shared is None:
        shared = {}
    if "design" not in shared:
        shared["design"], shared["trials"] = design_for(config), TrialCache()
    design = shared["design"]
    responder = SimResponder(SimObserver.parse(config.observer, config.seed), design.model,
                             load_profile(config.profile), config.speed_mm_s, config.force_n, shared["trials"])
    return run_session(config, design, responder, tmp_path, figures=figures), responder


def read_csv(path):
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_threshold_command_writes_log_metadata_result_and_print_quality_figures(tmp_path):
    out = tmp_path / "s"
    result = run_cli("experiment", "threshold", "grating-1mm", "--method", "staircase", "--afc", "3", "--rule",
                     "1u3d", "--observer", SIM, "--trials", "40", "--seed", "4", "--out", out, "--device", "null",
                     "--break-every", "15", "--participant", "P07", "--json", check=True)
    summary = json.loads(result.stdout)
    assert summary["unit"] == "friction contrast (1 - ratio)"
    low, high = summary["ci"]
    assert 0 < low <= summary["threshold"] <= high
    rows = read_csv(out / "trials.csv")
    assert [int(r["trial"]) for r in rows] == list(range(1, 41))
    assert {r["participant"] for r in rows} == {"P07"}
    assert [int(r["trial"]) for r in rows if r["break_before"] == "1"] == [16, 31]
    for row in rows:  # the log is self-consistent: correct means the answer was the target zone
        assert (row["response"] == row["target"]) == (row["correct"] == "1")
        assert float(row["rt_s"]) > 0
        assert f"zone {row['target']}:" in row["stimulus"]
    targets = [int(r["target"]) for r in rows[:39]]
    assert np.bincount(targets)[1:].tolist() == [13, 13, 13]  # counterbalanced in blocks of 3
    assert sum(r["reversal"] == "1" for r in rows) == summary["reversals"] > 0
    session = json.loads((out / "session.json").read_text())
    assert session["status"] == "complete" and session["seed"] == 4
    assert session["profile"]["resonance_hz"] == 25000
    assert {"ultraglide", "numpy", "scipy", "python"} <= set(session["versions"])
    assert session["model"]["spec"] == "stretched" and session["device"] == "null"
    for name in ("track", "psychometric"):
        with Image.open(out / f"{name}.png") as image:
            assert image.info["dpi"][0] >= 299
        assert (out / f"{name}.pdf").read_bytes().startswith(b"%PDF")
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary files left


def test_rendered_zones_show_the_level_the_procedure_asked_for():
    """The target zone's friction contrast, as the plate model says it was rendered, is the level."""
    texture = resolve_texture("grating-1mm")
    model, profile = ExponentialModel(), load_profile("sim-plate")
    design = StimulusDesign(texture, "contrast", Layout(3))
    for level in (0.05, 0.2, 0.5):
        trial = design.trial_texture(level, target=1)
        sampler = Sampler(trial, band_limited=False)
        middle = np.full(400, 30.0)
        zone_x = np.linspace(design.layout.zone_left_mm(1) + 1, design.layout.zone_left_mm(1) + 39, 400)
        ratio = sampler.ratio(zone_x, middle)
        assert ratio.max() == pytest.approx(1.0, abs=0.01) and ratio.min() == pytest.approx(1 - level, abs=0.01)
        other = sampler.ratio(zone_x - 50, middle)
        assert np.all(other == 1.0)
        rendered = render_offline(trial, design.layout, model, profile)
        assert rendered.zone_contrast[1] == pytest.approx(level, rel=0.1)
        assert rendered.zone_contrast[0] < 1e-6 and rendered.zone_contrast[2] < 1e-6
    uniform = StimulusDesign(texture, "amplitude", Layout(1), model=model)
    for amplitude in (2.0, 4.0):
        rendered = render_offline(uniform.trial_texture(amplitude, 0), uniform.layout, model, profile)
        assert rendered.zone_um_pp[0] == pytest.approx(amplitude, rel=0.01)
    contrast = with_contrast(texture, 0.3).values
    assert (contrast.min(), contrast.max()) == pytest.approx((0.7, 1.0), abs=1e-6)


@pytest.mark.slow
def test_dry_runs_recover_the_simulated_threshold(tmp_path):
    """A few seeds of each adaptive method: the interval holds the true 0.08 in most, every estimate is near it."""
    covered, shared = [], {}
    for method, seed in (("staircase", 1), ("staircase", 2), ("quest", 1), ("quest", 2)):
        outcome, responder = dry_run(tmp_path / f"{method}{seed}", method=method, trials=80, seed=seed, shared=shared,
                                     figures=False)  # the estimates are checked here; the figures elsewhere
        low, high = outcome.result["ci"]
        covered.append(low <= 0.08 <= high)
        assert 0.08 / 1.5 < outcome.result["threshold"] < 0.08 * 1.5, outcome.result
        assert responder.rendered_frames > 80 * 96000  # every trial's swipe (> 1 s at 96 kHz) was rendered
    assert sum(covered) >= 3, covered


@pytest.mark.slow
def test_dry_runs_recover_the_threshold_within_the_interval_in_most_seeds(tmp_path):
    covered, shared = [], {}
    for seed in range(20):
        outcome, _ = dry_run(tmp_path / str(seed), method="staircase", trials=80, seed=seed, bootstrap=300,
                             figures=False, shared=shared)  # the intervals are checked here; the figures elsewhere
        low, high = outcome.result["ci"]
        covered.append(low <= 0.08 <= high)
        assert outcome.figures == [] and not list((tmp_path / str(seed)).glob("*.p*"))  # none asked, none drawn
    assert sum(covered) >= 16, covered  # a 95 % interval: 19 of 20 on average; 16 or more with P > 0.98


def test_constant_preset_reproduces_the_papers_protocol(tmp_path):
    out = tmp_path / "v"
    result = run_cli("experiment", "constant", "--preset", "vezzoli2015", "--observer",
                     "sim:threshold=3,slope=4,false_alarm=0.05", "--seed", "1", "--out", out, "--json", check=True)
    summary = json.loads(result.stdout)
    rows = read_csv(out / "trials.csv")
    levels = [float(r["level"]) for r in rows]
    assert sorted(set(levels)) == [0.0, 2.0, 4.0] and len(rows) == 30
    assert all(sorted(levels[i:i + 3]) == [0.0, 2.0, 4.0] for i in range(0, 30, 3))  # random order, in blocks
    assert {r["response"] for r in rows} <= {"yes", "no"}
    for row in rows:  # the plate really vibrated at the level asked for
        assert float(row["rendered_um_pp"]) == pytest.approx(float(row["level"]), abs=0.02)
    session = json.loads((out / "session.json").read_text())
    assert session["config"]["force_n"] == 0.4 and "slippery" in session["question"]
    by_level = {item["level"]: item for item in summary["proportions"]}
    assert by_level[4.0]["p"] > by_level[2.0]["p"]
    assert summary["unit"] == "µm p-p" and summary["ci"][0] <= summary["threshold"] <= summary["ci"][1]


def _session_rows(directory):
    return [{k: v for k, v in row.items() if k != "time_utc"} for row in read_csv(directory / "trials.csv")]


def test_resume_after_a_kill_continues_the_same_procedure(tmp_path):
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    options = ["experiment", "threshold", "grating-1mm", "--method", "staircase", "--afc", "2", "--observer", SIM,
               "--trials", "50", "--seed", "8"]
    run_cli(*options, "--out", whole, "--no-figures", check=True)  # the reference log: its figures unused
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", *options, "--out", str(cut)], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        log = cut / "trials.csv"
        if log.exists() and log.read_text().count("\n") >= 12:
            break
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=30)
    logged = len(read_csv(cut / "trials.csv"))
    assert 11 <= logged < 50
    assert json.loads((cut / "session.json").read_text())["status"] == "running"
    with open(cut / "trials.csv", "a") as handle:  # as if killed while writing a row
        handle.write("P01,1,99,half a ro")
    result = run_cli("experiment", "threshold", "--resume", cut, check=True)
    assert "50 trials, complete" in result.stdout
    assert _session_rows(cut) == _session_rows(whole)
    assert json.loads((cut / "result.json").read_text())["threshold"] == pytest.approx(
        json.loads((whole / "result.json").read_text())["threshold"])
    assert json.loads((cut / "session.json").read_text())["resumed_at_trial"] == logged + 1


def test_resume_can_extend_a_session_and_sessions_can_go_without_figures(tmp_path):
    short, long = tmp_path / "short", tmp_path / "long"
    common = ["--method", "quest", "--afc", "2", "--observer", SIM, "--seed", "3"]
    result = run_cli("experiment", "threshold", "grating-1mm", *common, "--trials", "40", "--out", long,
                     "--no-figures", check=True)
    assert sorted(p.name for p in long.iterdir()) == ["result.json", "session.json", "trials.csv"]
    assert result.stdout.rstrip().endswith(f"files in {long}: trials.csv, session.json, result.json")
    run_cli("experiment", "threshold", "grating-1mm", *common, "--trials", "20", "--out", short, check=True)
    assert {"track.png", "track.pdf", "psychometric.png", "psychometric.pdf"} <= {p.name for p in short.iterdir()}
    result = run_cli("experiment", "threshold", "--resume", short, "--trials", "40", "--no-figures", "--json",
                     check=True)
    assert _session_rows(short) == _session_rows(long)
    assert json.loads(result.stdout)["figures"] == []
    # the figures of its first 20 trials would disagree with the log's 40: gone
    assert sorted(p.name for p in short.iterdir()) == ["result.json", "session.json", "trials.csv"]


@pytest.mark.parametrize("args, words", [
    (["threshold", "grating-1mm", "--observer", "sim:slope=2", "--trials", "5"], "threshold=T"),
    (["threshold", "grating-1mm", "--observer", SIM, "--trials", "5", "--vary", "wavelength", "--reference",
      "wood"], None),
    (["threshold", "wood", "--observer", SIM, "--trials", "5", "--vary", "wavelength"], "grating"),
    (["threshold", "no-such-texture", "--observer", SIM, "--trials", "5"], "no texture"),
    (["threshold", "grating-1mm", "--observer", SIM, "--trials", "5", "--device", "sim"], "--device null"),
    (["threshold", "grating-1mm", "--observer", SIM], "--trials"),
    (["threshold", "grating-1mm", "--observer", SIM, "--trials", "5", "--range", "0.1", "2"], "at most 1"),
    (["constant", "--observer", SIM], "--preset"),
    (["constant", "--preset", "vezzoli2015", "--observer", SIM, "--repeats", "0"], "--repeats"),
    (["constant", "--preset", "vezzoli2015", "--observer", SIM, "--levels", "0", "-1"], "in 0..10000, got -1"),
    (["threshold", "grating-1mm", "--observer", SIM, "--trials", "5", "--break-every", "-1"], "--break-every"),
    (["threshold", "grating-1mm", "--observer", SIM, "--trials", "5", "--interval", "bootstrap", "--bootstrap",
      "5"], "--bootstrap"),
    (["threshold", "grating-1mm", "--afc", "4"], "from 2 to 3, got 4"),
])
def test_bad_options_get_one_line_and_leave_no_files(tmp_path, args, words):
    out = tmp_path / "out"
    result = run_cli("experiment", *args, "--out", out)
    if words is None:  # a good combination, for contrast: wavelength against another texture runs
        assert result.returncode == 0, result.stderr
        return
    line = assert_one_line_error(result)
    assert words in line
    assert not out.exists()


def test_an_existing_session_is_not_overwritten(tmp_path):
    out = tmp_path / "s"
    run_cli("experiment", "threshold", "grating-1mm", "--observer", SIM, "--trials", "6", "--out", out, "--no-figures",
            check=True)
    before = (out / "trials.csv").read_bytes()
    line = assert_one_line_error(run_cli("experiment", "threshold", "grating-1mm", "--observer", SIM,
                                         "--trials", "6", "--out", out))
    assert "--resume" in line and (out / "trials.csv").read_bytes() == before
    assert "no session.json" in assert_one_line_error(run_cli("experiment", "threshold", "--resume",
                                                              tmp_path / "nothing"))


@pytest.mark.slow
def test_the_log_is_on_disk_after_each_trial(tmp_path):
    """fsync per trial: the CSV grows one complete row per trial while the session runs."""
    seen = []

    class Watching(SimResponder):
        def present(self, trial, level, target, design):
            rows = read_csv(tmp_path / "trials.csv")
            seen.append(len(rows))
            return super().present(trial, level, target, design)

    config = SessionConfig(texture="grating-1mm", observer=SIM, trials=8, bootstrap=10)
    design = design_for(config)
    run_session(config, design, Watching(SimObserver.parse(SIM), design.model, load_profile("sim-plate"), 100.0,
                                         0.5), tmp_path, figures=False)
    assert seen == list(range(8))



def test_a_live_session_without_a_display_says_so_and_writes_nothing(tmp_path):
    out = tmp_path / "live"
    result = run_cli("experiment", "threshold", "grating-1mm", "--trials", "5", "--out", out,
                     env={"DISPLAY": "", "WAYLAND_DISPLAY": "", "SDL_VIDEODRIVER": ""})
    assert "no display" in assert_one_line_error(result) and not out.exists()
