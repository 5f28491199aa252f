"""``texture info``'s "felt" figures: what a swipe at 50, 100 and 200 mm/s keeps of a texture's contrast, under the
model, the plate's limit and the force given, the lowest friction a swipe is felt at rising with speed under a
settled speed law."""

import json

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli
from ultraglide.render.physics.dynamics import FrictionDynamics
from ultraglide.render.physics.friction_models import StretchedExponentialModel
from ultraglide.render.planning import swipe_contrast
from ultraglide.textures.library import resolve_texture


def felt(*options):
    return json.loads(run_cli("texture", "info", "grating-1mm", "--json", *options, check=True).stdout)["felt"]


def stretched_at(amplitude_um_pp: float, force_n: float) -> float:
    """The stretched model's settled ratio at an amplitude, evaluated forward (not through its floor)."""
    return float(StretchedExponentialModel().relative_friction(np.array([amplitude_um_pp]), force_n)[0])


def test_the_default_is_the_stretched_models_floor_within_sim_plates_limit_and_the_published_dynamics():
    texture = resolve_texture("grating-1mm")
    floor = stretched_at(6.0, 0.5)  # sim-plate's limit is 6 µm p-p
    for entry, speed in zip(felt(), (50.0, 100.0, 200.0), strict=True):
        assert entry["speed_mm_s"] == speed and entry["floor"] == pytest.approx(floor, abs=1e-4)
        kept = swipe_contrast(texture, FrictionDynamics(), speed, floor, longest_s=0.5)
        assert entry["contrast_planned"] == pytest.approx(kept.planned, abs=1e-3)
        assert entry["rms_instantaneous"] == pytest.approx(kept.instantaneous_rms, abs=1e-3)


def test_under_a_speed_law_the_floor_is_the_static_one_within_the_limit_shrunk_by_the_speed():
    """s = 1: at v the plate's 6 µm act as 6 × 22 / v µm on the settled reduction (hand), so the floor at 200 mm/s
    is the static model's at 0.66 µm, and less of a fine grating is in reach: it is felt further from the texture."""
    laws = felt("--model", "speed:1:stretched")
    for entry in laws:
        assert entry["floor"] == pytest.approx(stretched_at(6.0 * 22.0 / entry["speed_mm_s"], 0.5), abs=1e-4)
    floors = [entry["floor"] for entry in laws]
    assert floors == sorted(floors) and floors[0] > stretched_at(6.0, 0.5)
    without = felt()
    assert laws[2]["rms_instantaneous"] > without[2]["rms_instantaneous"]  # less of the grating within reach


def test_the_force_and_the_profile_s_limit_set_the_floor():
    heavier = felt("--force", "1.5")
    assert heavier[0]["floor"] == pytest.approx(stretched_at(6.0, 1.5), abs=1e-4)
    assert heavier[0]["floor"] != pytest.approx(stretched_at(6.0, 0.5), abs=1e-3)  # the law depends on force


def test_the_words_name_the_model_the_limit_and_the_force():
    words = run_cli("texture", "info", "grating-1mm", "--model", "dynamic:speed:0.5:stretched", "--force", "1",
                    check=True).stdout
    assert "a finger with the published friction dynamics keeps (ours; dynamic:speed:0.5:stretched within 6 µm " \
        "p-p at 1 N)" in words
    assert words.count("lowest friction") == 3
    plain = run_cli("texture", "info", "grating-1mm", check=True).stdout
    assert "the published friction dynamics keeps (ours; dynamic within 6 µm p-p at 0.5 N)" in plain
    assert "lowest friction" not in plain


def test_the_json_says_what_the_figures_were_worked_out_under():
    facts = json.loads(run_cli("texture", "info", "grating-1mm", "--json", "--model", "dynamic", "--force", "1",
                               check=True).stdout)
    assert facts["felt_under"] == {"model": "dynamic", "dynamics": "published (Meyer et al. 2014)",
                                   "profile": "sim-plate", "limit_um_pp": 6.0, "force_n": 1.0}
    plain = json.loads(run_cli("texture", "info", "grating-1mm", "--json", check=True).stdout)
    assert plain["felt_under"]["model"] == "dynamic" and plain["felt_under"]["dynamics"].startswith("published")


def test_a_calibration_with_dynamics_fitted_on_the_plate_is_felt_with_them(tmp_path):
    """A participant's calibration whose dynamics were fitted on the plate (10 ms down, 50 ms back at 100 mm/s):
    the figures use them and say so, in words and in the JSON; they differ from the published dynamics' figures."""
    fitted = tmp_path / "p01.toml"
    fitted.write_text('ultraglide_calibration = 1\nmodel = "exponential"\n[parameters]\ntau_um_zp = 1.3\n'
                      '[dynamics]\nfitted = true\nonset_s = 0.01\nrecovery_s = 0.05\nreference_speed_mm_s = 100.0\n'
                      'speed_exponent = 0.5\nsource = "fitted on the plate, 16 edges (8 onsets, 8 recoveries)"\n')
    facts = json.loads(run_cli("texture", "info", "grating-1mm", "--json", "--model", fitted, check=True).stdout)
    assert facts["felt_under"]["dynamics"] == "the model's own, fitted on the plate, 16 edges (8 onsets, 8 recoveries)"
    words = run_cli("texture", "info", "grating-1mm", "--model", fitted, check=True).stdout
    assert "a finger with its own friction dynamics keeps" in words
    published = json.loads(run_cli("texture", "info", "grating-1mm", "--json", "--model", "exponential",
                                    check=True).stdout)
    assert facts["felt"] != published["felt"]


def test_a_bad_model_or_profile_is_one_line_and_exit_2():
    for options, said in ((["--model", "speed:3:stretched"], "speed"), (["--profile", "nope"], "profile"),
                          (["--force", "-1"], "force")):
        result = run_cli("texture", "info", "grating-1mm", *options)
        assert result.returncode == 2 and said in assert_one_line_error(result)
