"""``ultraglide model`` and ``ultraglide calibrate`` end to end, as a person runs them."""

import json
import re
import subprocess
import time

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from PIL import Image


def test_help_and_version_start_fast():
    start = time.perf_counter()
    result = subprocess.run([".venv/bin/ultraglide", "--help"], capture_output=True, text=True)
    assert result.returncode == 0 and "model" in result.stdout
    assert run_cli("--version").stdout.startswith("ultraglide ")
    # the help path must not import numpy; checked by importing it and looking
    probe = subprocess.run(
        [".venv/bin/python", "-c",
         "import sys, ultraglide.apps.cli.parser as cli; cli.build_parser(); print('numpy' in sys.modules)"],
        capture_output=True, text=True)
    assert probe.stdout.strip() == "False"
    assert time.perf_counter() - start < 30


def test_model_text_has_the_paper_worked_example():
    result = run_cli("model", "--force", "0.15", check=True)
    assert "detach amplitude" in result.stdout
    assert "1.15 µm p-p" in result.stdout


def test_model_json_keys_and_values():
    result = run_cli("model", "--force", "0.4", "--json", "--ratio", "0.85", check=True)
    data = json.loads(result.stdout)
    assert data["force_n"] == 0.4
    assert data["contact_area_mm2"] == pytest.approx(138.1 * 0.4 ** (2 / 3), rel=1e-9)
    assert data["normal_stiffness_n_per_m"] / data["tangential_stiffness_n_per_m"] == pytest.approx(2.8)
    assert 3.6 < data["glide_threshold_um_pp"] < 4.8
    curve = np.array(data["curve"])
    assert curve[0].tolist() == [0.0, 1.0] and curve[-1, 0] >= 8
    assert np.all(np.diff(curve[:, 1]) <= 0)
    a = data["amplitude_for_ratio_um_pp"]
    assert np.interp(a, curve[:, 0], curve[:, 1]) == pytest.approx(0.85, abs=5e-3)


def test_model_choice_and_unreachable_ratio():
    exp = json.loads(run_cli("model", "--model", "exponential", "--json", "--ratio", "0.2", check=True).stdout)
    assert exp["ratio_reachable"] is True
    paper = run_cli("model", "--ratio", "0.2", check=True).stdout
    assert "out of reach" in paper


def test_a_ratio_out_of_a_tables_reach_names_the_tables_largest_amplitude(tmp_path):
    table = tmp_path / "bench.csv"
    table.write_text("amplitude_um_pp,relative_friction\n0,1\n2,0.7\n4,0.3\n6,0.1\n")
    text = run_cli("model", "--model", f"table:{table}", "--ratio", "0.05", check=True).stdout
    assert "the lowest this model gives within 6 µm is 0.100 (clamped to 6.00 µm p-p)" in text


def test_model_plots_writes_figures_2_to_9(tmp_path):
    result = run_cli("model", "--plots", tmp_path / "figs", check=True)
    files = sorted((tmp_path / "figs").glob("*.png"))
    assert [f.name[:4] for f in files] == [f"fig{n}" for n in range(2, 10)]
    for file in files:
        with Image.open(file) as image:
            assert image.format == "PNG" and image.width >= 600 and image.height >= 400
            assert len(image.convert("L").getcolors(1 << 16)) > 10  # something was drawn
            assert image.info["dpi"][0] == pytest.approx(300, abs=1)  # print quality
        assert file.with_suffix(".pdf").read_bytes().startswith(b"%PDF")  # and a vector copy
    assert "wrote" in result.stdout


def test_the_friction_in_time_figure_docs_physics_names_is_the_one_model_plots_writes(tmp_path):
    physics = (ROOT / "docs" / "physics.md").read_text()
    said = re.search(r"`ultraglide model --model dynamic` prints the dynamics and, with `--plots DIR`,\s+"
                     r"draws `([\w-]+)\.png`/`\.pdf`", physics)
    assert said is not None, "docs/physics.md no longer says which figure model --model dynamic --plots draws"
    run_cli("model", "--model", "dynamic", "--plots", tmp_path, check=True)
    assert (tmp_path / f"{said[1]}.png").is_file() and (tmp_path / f"{said[1]}.pdf").is_file()


@pytest.mark.parametrize("args, fragment", [
    (["model", "--force", "-0.5"], "positive"),
    (["model", "--ratio", "1.5"], "ratio"),
    (["model", "--model", "squeeze"], "unknown model"),
    (["model", "--model", "table:/nonexistent.csv"], "no such file"),
    (["calibrate", "/nonexistent.csv", "-o", "x.toml"], "no such file"),
    (["model", "--force", "abc"], "not a number"),
])
def test_bad_input_is_one_line(args, fragment):
    assert fragment in assert_one_line_error(run_cli(*args))


def test_calibrate_end_to_end(tmp_path):
    data = tmp_path / "data.csv"
    rows = ["# synthetic, tau = 1.1 µm zero-to-peak", "amplitude_um_pp,relative_friction,force_n"]
    rows += [f"{a},{np.exp(-(a / 2) ** 2 / (2 * 1.1**2)):.6f},0.5" for a in np.linspace(0, 6, 9)]
    data.write_text("\n".join(rows) + "\n")
    cal = tmp_path / "cal.toml"
    result = run_cli("calibrate", data, "--model", "exponential", "-o", cal, check=True)
    assert "tau_um_zp = 1.1" in result.stdout and "rms residual" in result.stdout
    model = json.loads(run_cli("model", "--model", cal, "--json", "--ratio", "0.5", check=True).stdout)
    assert model["amplitude_for_ratio_um_pp"] == pytest.approx(2 * 1.1 * np.sqrt(2 * np.log(2)), rel=1e-3)


def test_calibrate_bad_csv_leaves_no_output(tmp_path):
    data = tmp_path / "bad.csv"
    data.write_text("amplitude_um_pp,friction\n1,0.5\n")
    cal = tmp_path / "cal.toml"
    assert "missing column" in assert_one_line_error(run_cli("calibrate", data, "-o", cal))
    assert not cal.exists()


def _multi_force_csv(path, scale=3.4, shape=1.7, exponent=0.4, noise=0.01):
    rng = np.random.default_rng(5)
    rows = ["amplitude_um_pp,relative_friction,force_n"]
    for force in (0.25, 0.5, 1.0):
        for a in np.linspace(0, 7, 11):
            r = np.exp(-(a / (scale * (force / 0.5) ** exponent)) ** shape) + rng.normal(0, noise)
            rows.append(f"{a:.3f},{max(r, 0.005):.5f},{force}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_calibrate_compare_ranks_models_and_writes_the_best_with_its_figure(tmp_path):
    data = _multi_force_csv(tmp_path / "three-forces.csv")
    cal = tmp_path / "cal.toml"
    result = json.loads(run_cli("calibrate", data, "--compare", "--json", "-o", cal, check=True).stdout)
    ranking = result["ranking"]
    assert ranking[0]["model"] == "stretched"
    scores = [r["cross_validation_rms"]["leave_one_force_out"] for r in ranking]
    assert scores == sorted(scores)
    assert ranking[0]["cross_validation_rms"]["leave_one_force_out"] < 0.03
    assert {"exponential", "paper", "paper-uniform", "table"} <= {r["model"] for r in ranking}
    fitted = ranking[0]["parameters"]
    assert fitted["force_exponent"]["value"] == pytest.approx(0.4, abs=4 * fitted["force_exponent"]["stderr"])
    assert set(result["written"]) == {str(cal), str(cal.with_suffix(".png")), str(cal.with_suffix(".pdf"))}
    with Image.open(cal.with_suffix(".png")) as image:
        assert image.info["dpi"][0] == pytest.approx(300, abs=1)
    assert cal.with_suffix(".pdf").read_bytes().startswith(b"%PDF")
    text = run_cli("calibrate", "apps/data/monnoyer2018-fit.csv", "--compare", check=True).stdout
    assert "1 force: the force law could not be tested" in text and "ranked by k-fold error" in text
    assert "1. exponential" in text or "1. stretched" in text  # the published Gaussian law and its superset


def test_calibrate_warns_in_one_line_and_never_advises_what_was_asked(tmp_path):
    # --bootstrap 0: the words checked come from the fit and its cross-validation; 200 resamples of the
    # paper model (the command's default) would only cost half a minute
    paper = run_cli("calibrate", "apps/data/monnoyer2018-fit.csv", "--model", "paper", "--bootstrap", "0",
                    check=True).stdout
    warnings = [line for line in paper.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and "friction_exponent" in warnings[0] and "physics" in warnings[0]
    data = _multi_force_csv(tmp_path / "three-forces.csv", exponent=0.8)
    exp = run_cli("calibrate", data, "--model", "exponential", "--bootstrap", "0", check=True).stdout
    assert "leave-one-force-out" in exp
    assert "--model exponential" not in exp and "--compare" in exp  # poor across forces: points to --compare


def test_model_report_is_one_pdf_page(tmp_path):
    report = tmp_path / "report.pdf"
    run_cli("model", "--model", "stretched", "--force", "0.3", "--report", report, check=True)
    content = report.read_bytes()
    assert content.startswith(b"%PDF")
    assert len(re.findall(rb"/Type\s*/Page\b", content)) == 1


def test_calibration_file_with_an_infinite_parameter_is_one_line(tmp_path):
    cal = tmp_path / "cal.toml"
    cal.write_text("ultraglide_calibration = 1\nmodel = \"stretched\"\n[parameters]\nscale_um_pp = inf\nshape = 2.0\n")
    line = assert_one_line_error(run_cli("model", "--model", cal))
    assert "scale_um_pp" in line and "[0.05, 100]" in line
