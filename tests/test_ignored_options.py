"""Options accepted and then ignored (issue 26): an option that silently does nothing in some combination is
refused in one line that says when it counts, before any work, and nothing is written. The combinations were
found by walking every command's options (``model --data`` without ``--plots`` was the first)."""

import pytest
from test_inputs import no_hang
from ultraglide.apps.cli.main import main

SIM = "sim:threshold=0.1,slope=3"
CASES = [  # a command line that would run, with one option it would have ignored; what the refusal says
    (["model", "--data", "{d}/points.csv"], "--plots DIR"),
    (["model", "--figure-width", "page"], "--plots DIR or --report"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--trajectory", "{d}/log.csv", "--duration-s", "3"],
     "--duration-s shapes a swipe"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--trajectory", "{d}/log.csv", "--path", "circle"],
     "--path shapes a swipe"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--trajectory", "{d}/log.csv", "--start", "1,1"],
     "--start shapes a swipe"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--radius-mm", "5"], "--path circle"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--path", "circle", "--zigzag-width-mm", "5"], "--path zigzag"),
    (["export", "grating-1mm", "-o", "{d}/a.wav", "--figure-width", "page"], "--figure-width lays out --plot"),
    (["play", "grating-1mm", "--device", "null", "--trajectory", "{d}/log.csv", "--speed-mm-s", "50"],
     "--speed-mm-s shapes a swipe"),
    (["play", "grating-1mm", "--device", "null", "--radius-mm", "5"], "--path circle"),
    (["author", "{d}/image.png", "-o", "{d}/t.png", "--seam-band", "0.2"], "add --seamless"),
    (["author", "{d}/image.png", "-o", "{d}/t.png", "--seam-method", "mirror"], "add --seamless"),
    (["author", "{d}/image.png", "-o", "{d}/t.png", "--seamless", "--seam-method", "mirror", "--seam-band", "0.2"],
     "mirror has none"),
    (["author", "{d}/image.png", "-o", "{d}/t.png", "--auto-levels-clip", "2"], "tunes --auto-levels"),
    (["calibrate", "{d}/points.csv", "--passes", "3"], "--passes is for a calibration on the plate"),
    (["calibrate", "{d}/points.csv", "--no-window"], "--no-window is for a calibration on the plate"),
    (["calibrate", "{d}/points.csv", "--profile", "sim-plate-small"], "--profile is for a calibration on the plate"),
    (["calibrate", "{d}/points.csv", "--finger-drift", "0"], "add --device sim"),
    (["calibrate", "{d}/points.csv", "--compare", "--model", "paper"], "--compare fits every model"),
    (["calibrate", "{d}/points.csv", "--figure-width", "page"], "add -o"),
    (["experiment", "threshold", "--resume", "{d}/session", "--seed", "4"], "--seed is kept in the session"),
    (["experiment", "threshold", "--resume", "{d}/session", "--method", "quest"], "--method is kept"),
    (["experiment", "threshold", "--resume", "{d}/session", "--out", "{d}/other"], "leave out --out"),
    (["experiment", "threshold", "grating-1mm", "--resume", "{d}/session"], "leave out grating-1mm"),
    (["experiment", "constant", "--resume", "{d}/session", "--levels", "1", "2"], "--levels is kept"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM, "--out", "{d}/s",
      "--bootstrap", "50"], "add --interval bootstrap"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM, "--out", "{d}/s",
      "--windowed"], "a simulated observer has none"),
    (["plate", "sweep", "-o", "{d}/p.toml", "--sensor", "audio:1"], "sweeping an audio output"),
    (["plate", "sweep", "-o", "{d}/p.toml", "--device", "null", "--sensor-um-per-unit", "2"],
     "sweeping an audio output"),
    (["plate", "sweep", "-o", "{d}/p.toml", "--device", "audio:1", "--profile", "sim-plate",
      "--sensor-um-per-unit", "2"], "add --sensor"),
    (["plate", "sweep", "-o", "{d}/p.toml", "--figure-width", "page"], "add --plot"),
    (["texture", "show", "grating-1mm", "--window", "--dpi", "150"], "--window writes none"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--out", "{d}/s", "--speed-mm-s", "50"],
     "add --observer"),
    (["experiment", "constant", "--preset", "vezzoli2015", "--out", "{d}/s", "--speed-mm-s", "50"], "add --observer"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM, "--out", "{d}/s", "--method",
      "quest", "--rule", "1u3d"], "--rule is for a staircase"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM, "--out", "{d}/s", "--method",
      "quest", "--start-level", "0.3"], "--start-level is for a staircase"),
    (["experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM, "--out", "{d}/s", "--method",
      "quest", "--interval", "bootstrap"], "--interval is for a staircase"),
    (["play", "grating-1mm", "--duration-s", "0.1", "--finger-log-hz", "100"], "add --finger-log"),
    (["plate-sim", "--finger-log-hz", "100"], "add --finger-log"),
]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """What the command lines read, good: points, a touch log, an image, a session to resume."""
    import numpy as np
    from conftest import run_cli
    from PIL import Image

    tmp_path = tmp_path_factory.mktemp("inputs")
    (tmp_path / "points.csv").write_text("amplitude_um_pp,relative_friction\n"
                                         + "".join(f"{a},{1 - 0.08 * a}\n" for a in range(8)))
    (tmp_path / "log.csv").write_text("t_s,x_mm,y_mm\n0,1,5\n0.5,10,5\n")
    Image.fromarray(np.tile(np.linspace(0, 255, 64, dtype=np.uint8), (32, 1))).save(tmp_path / "image.png")
    run_cli("experiment", "threshold", "grating-1mm", "--trials", "6", "--observer", SIM, "--out",
            tmp_path / "session", "--no-figures", check=True)
    return tmp_path


@pytest.mark.parametrize("args, words", CASES, ids=[" ".join(args[:2]) + " " + words for args, words in CASES])
def test_an_option_the_combination_ignores_is_refused(inputs, capsys, args, words):
    before = sorted(p.name for p in inputs.rglob("*"))
    argv = [arg.format(d=inputs) for arg in args]
    with no_hang(300):
        status = main(argv)
    error = capsys.readouterr().err.strip()
    assert status == 2 and "\n" not in error and words in error, (argv, error)
    assert sorted(p.name for p in inputs.rglob("*")) == before  # nothing written
