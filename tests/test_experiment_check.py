"""The stimulus check: stimuli built as asked, rendered along the swipe, refused when they do not deliver."""

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import assert_one_line_error, run_cli

from ultraglide.experiment import (
    Block,
    Condition,
    Design,
    Stimulus,
    StimulusCheckError,
    check_stimuli,
    run,
    zone_texture,
)


def rating_design(*stimuli, pair=False):
    named = {s.name: s for s in stimuli}
    if pair:
        conditions = {"pair": Condition("pair", stimuli[0].name, stimuli[1].name)}
        blocks = (Block("b", "afc", ("pair",), repeats=2),)
    else:
        conditions = {s.name: Condition(s.name, s.name) for s in stimuli}
        blocks = (Block("b", "rating", tuple(conditions), repeats=1),)
    return Design("check", named, conditions, blocks)


def test_transforms_set_contrast_mean_scale_and_rotation_as_asked():
    zone = (40.0, 40.0)
    texture = zone_texture(Stimulus("s", "grating-1mm", contrast=0.3, mean=0.6), zone)
    values = texture.values.astype(float)
    assert values.max() - values.min() == pytest.approx(0.3, abs=1e-3)
    assert values.mean() == pytest.approx(0.6, abs=1e-4)
    # scale 2: a 1 mm grating becomes a 2 mm one; the row's spectrum peaks at 0.5 cycles/mm
    wide = zone_texture(Stimulus("s", "grating-1mm", scale=2.0), zone)
    row = wide.values[wide.rows // 2].astype(float)
    spectrum = np.abs(np.fft.rfft(row - row.mean()))
    frequencies = np.fft.rfftfreq(len(row), d=wide.width_mm / wide.cols)
    assert frequencies[np.argmax(spectrum)] == pytest.approx(0.5, abs=0.03)
    # rotation 90°: the stripes run along x, so a row is (nearly) uniform and a column carries the grating
    turned = zone_texture(Stimulus("s", "grating-1mm", rotation_deg=90.0), zone).values.astype(float)
    assert np.ptp(turned[turned.shape[0] // 2]) < 0.02 < 0.5 < np.ptp(turned[:, turned.shape[1] // 2])


def test_a_grating_delivers_its_contrast_and_mean_along_the_swipe():
    report = check_stimuli(rating_design(Stimulus("g", "grating-2mm", contrast=0.3)))
    figures = report.figures["g"]
    assert report.passed
    # by hand: a sine grating rescaled to [0.7, 1]: contrast 0.3, mean 0.85 on the path
    assert figures.path_contrast == pytest.approx(0.3, abs=0.005)
    assert figures.asked_mean == pytest.approx(0.85, abs=0.005)
    assert figures.delivered_contrast == pytest.approx(0.3, rel=0.1)
    assert figures.delivered_mean == pytest.approx(0.85, abs=0.02)


def test_under_friction_dynamics_the_check_judges_the_friction_felt():
    """At 100 mm/s a 1 mm grating modulates friction at 100 Hz: through the finger's fastest time constant (the 5 ms
    onset) a first-order lag keeps at most 1 / sqrt(1 + (2π 100 Hz 5 ms)²) = 0.30 of a swing, so under half of the
    0.3 asked is felt and the check refuses it, saying why; the static model's check (the ratio the plate
    commands) passes it. A 20 mm grating (5 Hz) through the slowest, the 32.8 ms recovery at 100 mm/s, keeps at
    least 1 / sqrt(1 + (2π 5 Hz 32.8 ms)²) = 0.70 of it: it passes felt too."""
    fine, coarse = Stimulus("fine", "grating-1mm", contrast=0.3), Stimulus("coarse", "grating-2mm", contrast=0.3,
                                                                             scale=10.0)
    static = check_stimuli(rating_design(fine, coarse))
    felt = check_stimuli(replace(rating_design(fine, coarse), model="dynamic"))
    assert static.passed, static.failures
    lowpass = 1 / np.sqrt(1 + (2 * np.pi * 100.0 * 0.005) ** 2)
    assert felt.figures["fine"].delivered_contrast < lowpass * 0.3 < 0.5 * 0.3
    assert felt.figures["coarse"].delivered_contrast > 1 / np.sqrt(1 + (2 * np.pi * 5.0 * 0.0328) ** 2) * 0.3 * 0.9
    assert not felt.passed and len(felt.failures) == 1
    assert "stimulus 'fine' delivers a friction contrast of" in felt.failures[0]
    assert "the finger's friction dynamics" in felt.failures[0] and "judged as felt" in felt.failures[0]
    assert felt.felt and not static.felt and felt.as_dict()["felt"] is True


def test_under_friction_dynamics_a_recorded_path_is_judged_felt_too(tmp_path):
    """The check's recorded-path branch takes the felt ratio at the path's own speed: a straight stroke at
    100 mm/s across a 1 mm grating keeps under the 0.30 bound of the 0.3 asked (refused, along that path), and
    across a 20 mm grating more than 0.70 of it; under the static model both pass along the path."""
    fine, coarse = Stimulus("fine", "grating-1mm", contrast=0.3), Stimulus("coarse", "grating-2mm", contrast=0.3,
                                                                             scale=10.0)
    stroke = touch_log(tmp_path / "stroke.csv", 2.0, 20.0, 38.0, 20.0, seconds=0.36)  # 100 mm/s
    design = replace(rating_design(fine, coarse), check_paths=(stroke,))
    static = check_stimuli(design)
    felt = check_stimuli(replace(design, model="dynamic"))
    assert not [f for f in static.failures if "recorded path" in f], static.failures
    along = {name: felt.figures[f"{name} along {stroke}"] for name in ("fine", "coarse")}
    assert along["fine"].delivered_contrast < 0.30 * 0.3
    assert along["coarse"].delivered_contrast > 0.70 * 0.3 * 0.9
    assert any("stimulus 'fine' delivers a friction contrast" in f and f"along the recorded path {stroke}" in f
               and "judged as felt" in f for f in felt.failures), felt.failures


def test_the_check_command_says_the_model_and_that_the_figures_are_felt(tmp_path):
    from ultraglide.experiment import to_toml

    design = tmp_path / "design.toml"
    coarse = Stimulus("coarse", "grating-2mm", contrast=0.3, scale=10.0)
    for model, words in (("dynamic", "felt through the finger's friction dynamics"), ("stretched", "delivered")):
        design.write_text(to_toml(replace(rating_design(coarse), model=model)))
        text = run_cli("experiment", "check", str(design), check=True).stdout
        assert f"model {model})" in text.splitlines()[0]
        assert f"on the path / {words}; mean ratio asked / {words}):" in text


def test_a_texture_whose_features_the_swipe_never_crosses_is_refused():
    # a grating turned 90°: its stripes run along the swipe; and a 2 mm checkerboard, whose squares meet on the
    # zone's middle line (20 mm = 10 squares), where the lookup is the mean of both rows: both uniform to the finger
    for stimulus in (Stimulus("turned", "grating-1mm", contrast=0.3, rotation_deg=90.0),
                     Stimulus("checks", "checkerboard-2mm", contrast=0.3)):
        report = check_stimuli(rating_design(stimulus))
        assert report.figures[stimulus.name].delivered_contrast < 0.01
        assert report.failures == [f"stimulus {stimulus.name!r} delivers a friction contrast of "
                                   f"{report.figures[stimulus.name].delivered_contrast:.4f} along the swipe where the "
                                   "design asks 0.3000 (the swipe along the zone's middle does not cross its features)"]
        with pytest.raises(StimulusCheckError, match=f"stimulus '{stimulus.name}' delivers a friction contrast"):
            run(rating_design(stimulus), observer="sim:threshold=0.1")


def test_two_stimuli_meant_to_differ_in_texture_only_must_not_differ_in_mean_friction():
    # a sine grating and a square one of 25 % duty, both at contrast 0.3: the sine's mean is 0.85, the square's is
    # 0.7·duty + 1·(1 − duty) or the other way round: 0.775 or 0.925; either way 0.075 from the sine's
    sine = Stimulus("sine", "grating-2mm", contrast=0.3)
    square = Stimulus("square", "grating-square-2mm-duty25", contrast=0.3)
    report = check_stimuli(rating_design(sine, square, pair=True))
    assert abs(report.figures["sine"].delivered_mean - report.figures["square"].delivered_mean) == pytest.approx(
        0.075, abs=0.02)
    assert any("meant to differ in texture only, but their delivered mean friction ratios differ" in failure
               for failure in report.failures)
    # given the same mean, they pass
    even = check_stimuli(rating_design(Stimulus("sine", "grating-2mm", contrast=0.3, mean=0.75),
                                       Stimulus("square", "grating-square-2mm-duty25", contrast=0.3, mean=0.75),
                                       pair=True))
    assert even.passed, even.failures


def test_a_failing_design_exits_2_naming_the_stimulus_and_accept_check_records_it(tmp_path):
    design = tmp_path / "turned.toml"
    design.write_text("""
[stimuli.turned]
texture = "grating-1mm"
contrast = 0.3
rotation_deg = 90.0
[[conditions]]
name = "c"
stimulus = "turned"
[[blocks]]
task = "rating"
conditions = ["c"]
repeats = 2
""", encoding="utf-8")
    result = run_cli("experiment", "run", design, "--participant", "P01", "--out", tmp_path / "out", "--observer",
                     "sim:threshold=0.1")
    line = assert_one_line_error(result)
    assert result.returncode == 2 and "stimulus 'turned' delivers a friction contrast of 0.0" in line
    assert not (tmp_path / "out").exists()  # nothing written
    assert run_cli("experiment", "check", design).returncode == 2
    accepted = run_cli("experiment", "run", design, "--participant", "P01", "--out", tmp_path / "out", "--observer",
                       "sim:threshold=0.1", "--accept-check", check=True)
    assert "warning: stimulus check accepted despite: stimulus 'turned'" in accepted.stderr
    session = json.loads((tmp_path / "out" / "session.json").read_text())
    assert session["warnings"][0].startswith("stimulus check accepted despite: stimulus 'turned'")
    assert session["stimulus_check"]["passed"] is False


def test_the_threshold_command_refuses_a_library_texture_the_swipe_never_crosses(tmp_path):
    # the case: every trial's rendered contrast was 0.0000 on a library texture whose features lie off
    # the zone's middle line (dots), so target and reference differed in mean friction only
    out = tmp_path / "s"
    result = run_cli("experiment", "threshold", "dots", "--trials", "5", "--observer", "sim:threshold=0.1", "--out",
                     out, "--no-figures")
    line = assert_one_line_error(result)
    assert result.returncode == 2
    assert "stimulus 'stimulus at level 0.6' delivers a friction contrast of 0.0000" in line
    assert "does not cross its features" in line and not out.exists()
    accepted = run_cli("experiment", "threshold", "dots", "--trials", "5", "--observer", "sim:threshold=0.1", "--out",
                       out, "--no-figures", "--accept-check", check=True)
    assert "warning: stimulus check accepted despite" in accepted.stderr
    session = json.loads((out / "session.json").read_text())
    assert session["stimulus_check"]["passed"] is False and len(session["warnings"]) == 1


def touch_log(path, x0, y0, x1, y1, seconds=1.0, rate_hz=120):
    t = np.arange(int(seconds * rate_hz) + 1) / rate_hz
    x, y = x0 + (x1 - x0) * t / seconds, y0 + (y1 - y0) * t / seconds
    path.write_text("t_s,x_mm,y_mm\n" + "".join(f"{a:.5f},{b:.4f},{c:.4f}\n" for a, b, c in zip(t, x, y, strict=True)))
    return str(path)


def test_a_recorded_path_that_never_crosses_the_features_is_refused_naming_it(tmp_path):
    # a 4 mm grating whose stripes run along y: the swipe (along x) crosses them, a path along y never does
    stripes = Stimulus("stripes", "grating-1mm", contrast=0.3, scale=4.0)
    across = touch_log(tmp_path / "across.csv", 5.0, 5.0, 35.0, 35.0)
    along = touch_log(tmp_path / "along.csv", 20.0, 5.0, 20.0, 35.0)
    design = rating_design(stripes)
    report = check_stimuli(Design(**{**design.__dict__, "check_paths": (across,)}))
    assert report.passed, report.failures
    crossing = report.figures[f"stripes along {across}"]
    assert crossing.path_contrast == pytest.approx(0.3, abs=0.02)  # the whole sinusoid crossed
    assert crossing.delivered_contrast >= 0.5 * 0.3
    report = check_stimuli(Design(**{**design.__dict__, "check_paths": (across, along)}))
    assert report.figures[f"stripes along {along}"].path_contrast < 0.01  # x fixed: one stripe's value
    assert len(report.failures) == 1
    assert f"along the recorded path {along}" in report.failures[0]
    assert "the path does not cross its features" in report.failures[0]


def test_check_paths_go_through_the_toml_and_a_path_off_the_zone_is_refused_in_one_line(tmp_path):
    from ultraglide.experiment import design_from_toml, to_toml

    off = touch_log(tmp_path / "off.csv", 60.0, 5.0, 90.0, 5.0)  # right of a 40 mm zone
    design = rating_design(Stimulus("g", "grating-1mm", contrast=0.3, scale=4.0))
    text = to_toml(Design(**{**design.__dict__, "check_paths": (off,)}))
    assert design_from_toml(text).check_paths == (off,)
    with_effects = rating_design(Stimulus("g", "grating-1mm", effects="buzz.ahap"))
    assert design_from_toml(to_toml(with_effects)).stimuli["g"].effects == "buzz.ahap"
    toml = tmp_path / "design.toml"
    toml.write_text(text)
    result = run_cli("experiment", "check", str(toml))
    line = assert_one_line_error(result)
    assert "rig.check_paths[0]" in line and "never enters the zone" in line and result.returncode == 2


def test_a_gltf_scenes_friction_map_is_a_stimulus_that_delivers_as_its_source_does(tmp_path):
    scene = tmp_path / "grating.glb"
    written = run_cli("texture", "export-gltf", "grating-2mm", "-o", str(scene))
    assert written.returncode == 0, written.stderr
    from_scene = check_stimuli(rating_design(Stimulus("scene", str(scene), contrast=0.3)))
    from_library = check_stimuli(rating_design(Stimulus("library", "grating-2mm", contrast=0.3)))
    assert from_scene.passed, from_scene.failures
    scene_figures, library_figures = from_scene.figures["scene"], from_library.figures["library"]
    assert scene_figures.path_contrast == pytest.approx(library_figures.path_contrast, abs=0.01)
    assert scene_figures.delivered_contrast == pytest.approx(library_figures.delivered_contrast, abs=0.02)
    assert scene_figures.delivered_mean == pytest.approx(library_figures.delivered_mean, abs=0.01)


def test_a_stimulus_plays_its_temporal_effects_on_its_own_zone_only(tmp_path):
    from ultraglide.textures.compose import Placement, compose

    from ultraglide.experiment.check import Rig
    from ultraglide.experiment.stimuli import Layout, render_offline

    buzz = tmp_path / "buzz.json"  # a 40 Hz friction drop of 0.4 while the finger is anywhere on the zone
    buzz.write_text('{"effects_version": 1, "bindings": [{"trigger": {"on": "while"}, '
                    '"effect": {"type": "sine", "frequency_hz": 40, "depth": 0.4}}]}')
    flat = Stimulus("flat", "grating-1mm", contrast=0.0)  # uniform friction at rest: no contrast of its own
    buzzing = Stimulus("buzzing", "grating-1mm", contrast=0.0, effects=str(buzz))
    design = rating_design(flat, buzzing)
    rig = Rig(design)
    zones = [zone_texture(s, rig.zone_mm) for s in (buzzing, flat)]
    layout = Layout(2, rig.zone_mm, rig.gap_mm)
    trial = compose(layout.size_mm, [Placement(z, layout.zone_left_mm(i), layout.gap_mm) for i, z in enumerate(zones)],
                    1.0, px_per_mm=10.0)
    rendered = render_offline(trial, layout, rig.model, rig.profile, rig.speed_mm_s, rig.force_n)
    # the sine swings the ratio from 1 down to 0.6 and back while on the first zone; the second stays at rest
    assert rendered.zone_contrast[0] > 0.5 * 0.4
    assert rendered.zone_contrast[1] < 0.01
    assert rendered.zone_mean_ratio[0] == pytest.approx(1.0 - 0.2, abs=0.05)  # the sine's mean drop is depth / 2
    assert check_stimuli(design).figures["buzzing"].delivered_contrast > 0.5 * 0.4


def test_a_stimulus_whose_effects_cannot_be_read_is_refused_naming_it(tmp_path):
    from ultraglide.experiment import ExperimentError

    bad = tmp_path / "bad.json"
    bad.write_text('{"effects_version": 1, "bindings": [{"trigger": {"on": "never"}, "effect": 1}]}')
    with pytest.raises(ExperimentError, match=r"stimuli\.s\.effects: "):
        check_stimuli(rating_design(Stimulus("s", "grating-1mm", contrast=0.3, effects=str(bad))))


# ---- a mean that pushes a stimulus's ratios outside 0..1 at a level it may take -----------------------------------
# The design's contrast and mean are what the plate is asked for, exactly (docs/experiments.md): a level that cannot
# be built around the mean is refused before anything is rendered, naming the stimulus, the level and what to change.
# By hand, for a sine grating (its rescaled map's mean halfway up its span): at contrast c around mean m its ratios
# lie in m ± c/2, so at m = 0.8 contrast 0.6 gives 0.5..1.1, fits up to c = 2 (1 - m) = 0.4, and at c = 0.6 the
# mean must lie within 0.3..0.7.

RANGE_TOP = ("stimulus 'g' at level 0.6 (the top of conditions.c.range)", "lower the top of conditions.c.range to")
UNFIT = {
    "staircase": ("[[conditions]]\nname = 'c'\nstimulus = 'g'\nrange = [0.05, 0.6]\n[[blocks]]\n"
                  "task = 'staircase'\nconditions = ['c']\ntrials = 6\n", *RANGE_TOP),
    "constant": ("[[conditions]]\nname = 'c'\nstimulus = 'g'\nlevels = [0.1, 0.6, 0.3]\n[[blocks]]\n"
                 "task = 'constant'\nconditions = ['c']\nrepeats = 2\n",
                 "stimulus 'g' at level 0.6 (the largest of conditions.c.levels)",
                 "lower conditions.c.levels to at most"),
    "adjustment": ("[stimuli.ref]\ntexture = 'grating-1mm'\ncontrast = 0.2\n[[conditions]]\nname = 'c'\n"
                   "stimulus = 'g'\nreference = 'ref'\nrange = [0.05, 0.6]\n[[blocks]]\ntask = 'adjustment'\n"
                   "conditions = ['c']\nrepeats = 2\n", *RANGE_TOP),
    "rating": ("[[conditions]]\nname = 'c'\nstimulus = 'g'\n[[blocks]]\ntask = 'rating'\nconditions = ['c']\n"
               "repeats = 2\n", "stimulus 'g': a friction contrast of 0.6", "lower stimuli.g.contrast to"),
}


def unfit_design(tmp_path, task, mean=0.8, top=None):
    body, _, _ = UNFIT[task]
    contrast = "contrast = 0.6\n" if task == "rating" else ""
    if top is not None:  # the figure the refusal said, in place of 0.6
        body = body.replace("0.6", top)
        contrast = contrast.replace("0.6", top)
    path = tmp_path / f"{task}.toml"
    path.write_text(f"[experiment]\nseed = 2\n[stimuli.g]\ntexture = 'grating-1mm'\nmean = {mean}\n{contrast}{body}",
                    encoding="utf-8")
    return path


@pytest.mark.parametrize("task", list(UNFIT))
def test_a_mean_the_contrast_cannot_fit_at_a_level_is_refused_naming_the_level_and_the_change(tmp_path, task):
    import re

    _, names, change = UNFIT[task]
    path = unfit_design(tmp_path, task)
    result = run_cli("experiment", "check", path)
    line = assert_one_line_error(result)
    assert result.returncode == 2 and result.stdout == ""
    assert names in line and "around a mean friction ratio of 0.8 puts its ratios at 0.500..1.100, outside 0..1" in line
    found = re.search(r"its contrast fits up to ([0-9.]+): (.*) ([0-9.]+), or set stimuli\.g\.mean within "
                      r"([0-9.]+)\.\.([0-9.]+)$", line)
    assert found and found.group(2) == change, line
    fits, said, low_mean, high_mean = (float(found.group(i)) for i in (1, 3, 4, 5))
    assert fits == said == pytest.approx(0.4, abs=0.002)
    assert (low_mean, high_mean) == pytest.approx((0.3, 0.7), abs=0.002)
    # each change it names makes a design that can be built (the plate's reach is the check's other criteria: put aside)
    for changed in (unfit_design(tmp_path, task, top=found.group(1)), unfit_design(tmp_path, task, mean=low_mean),
                    unfit_design(tmp_path, task, mean=high_mean)):
        assert run_cli("experiment", "check", changed, "--accept-check").returncode == 0


def test_run_refuses_an_unfit_mean_before_anything_is_written_or_served(tmp_path):
    path = unfit_design(tmp_path, "adjustment")
    for how in (["--observer", "sim:threshold=0.1"], ["--serve", "--port", "0", "--device", "sim", "--json"]):
        result = run_cli("experiment", "run", path, "--participant", "P01", "--out", tmp_path / "out", *how)
        line = assert_one_line_error(result)
        assert result.returncode == 2 and "stimulus 'g' at level 0.6 (the top of conditions.c.range)" in line
        assert result.stdout == ""  # no page address: no participant reached
        assert not (tmp_path / "out").exists()
    # the Python API refuses it too, the check left out (never for a participant): before any trial or file
    from ultraglide.experiment import ExperimentError, load_design

    with pytest.raises(ExperimentError, match=r"stimulus 'g' at level 0\.6 .* outside 0\.\.1"):
        run(load_design(path), observer="sim:threshold=0.1", out=tmp_path / "api", check=False)
    assert not (tmp_path / "api").exists()
