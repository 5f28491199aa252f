"""--no-planning: a dynamic model's renderer commands the texture's ratio each instant, as its static model does."""

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.io import wavfile


def export(tmp_path, name, *options):
    path = tmp_path / f"{name}.wav"
    result = subprocess.run([sys.executable, "-m", "ultraglide", "export", "grating-1mm", "--duration-s", "0.5",
                             "-o", str(path), *options], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return wavfile.read(path)[1].astype(float)


@pytest.mark.filterwarnings("ignore::scipy.io.wavfile.WavFileWarning")  # our metadata chunk, which scipy skips
def test_without_planning_the_dynamic_model_plays_its_static_model_and_with_planning_it_does_not(tmp_path):
    static = export(tmp_path, "static", "--model", "stretched")
    unplanned = export(tmp_path, "unplanned", "--model", "dynamic", "--no-planning")
    planned = export(tmp_path, "planned", "--model", "dynamic")
    np.testing.assert_array_equal(unplanned, static)  # `dynamic` is the stretched law with the finger's lag
    assert np.sqrt(np.mean((planned - static) ** 2)) > 0.05 * np.sqrt(np.mean(static**2))
    np.testing.assert_array_equal(export(tmp_path, "default"), planned)  # the default model plans


@pytest.mark.parametrize("command", [["export", "-o", "never.wav"], ["play", "--device", "sim"]])
def test_no_planning_with_a_model_without_dynamics_is_refused_in_one_line(tmp_path, command):
    result = subprocess.run([sys.executable, "-m", "ultraglide", command[0], "grating-1mm", *command[1:],
                             "--model", "stretched", "--no-planning"], capture_output=True, text=True, timeout=300,
                            cwd=tmp_path)
    assert result.returncode != 0 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and "--model dynamic" in result.stderr
    assert not (tmp_path / "never.wav").exists()


@pytest.mark.parametrize(("options", "words", "planned"), [
    ([], "model: dynamic (with the published friction dynamics): the friction felt is planned", True),
    (["--no-planning"], "model: dynamic (with the published friction dynamics): each instant's ratio asked for "
                        "(--no-planning)", False),
    (["--model", "stretched"], "model: stretched (static): each instant's ratio asked for", False),
])
def test_export_says_the_model_and_whether_it_planned(tmp_path, options, words, planned):
    """The default plans without being asked: export says so (its words, and its JSON's model and planned), and
    what it says is what the envelope shows (the planned ratio differs from the texture's only where it plans)."""
    csv = tmp_path / "envelope.csv"
    run = [sys.executable, "-m", "ultraglide", "export", "grating-1mm", "--duration-s", "0.3", "-o",
           str(tmp_path / "out.wav"), "--envelope-csv", str(csv), *options]
    text = subprocess.run(run, capture_output=True, text=True, timeout=300, check=True).stdout
    assert words in text.splitlines()
    facts = json.loads(subprocess.run([*run, "--json"], capture_output=True, text=True, timeout=300,
                                      check=True).stdout)
    assert (facts["model"], facts["planned"]) == (options[1] if options[:1] == ["--model"] else "dynamic", planned)
    table = np.genfromtxt(csv, delimiter=",", names=True)
    assert bool(np.any(table["planned_ratio"] != table["target_ratio"])) == planned
