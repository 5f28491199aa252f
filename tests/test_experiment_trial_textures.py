"""What a design's trials play: each zone as the stimulus check rendered it (a varied stimulus keeps its mean at
every level), and the method of adjustment's textures built from the stimulus loaded and sampled once, the same
arrays, bit for bit, as built afresh for every level."""

import numpy as np
import pytest
from ultraglide.textures.compose import Placement, compose

from ultraglide.experiment import Block, Condition, Design, Stimulus, plan, run, zone_texture
from ultraglide.experiment.responders import Answer


class Recorder:
    """A participant's interface that keeps what each trial presents and answers at once (interval 1, the level
    presented)."""

    def __init__(self):
        self.shown = []

    def present(self, shown):
        self.shown.append(shown)
        return Answer(shown.level if shown.trial.task == "adjustment" else 0, 0.5)

    def take_break(self, trial, message=""):
        return True


def zone_values(texture, layout, zone):
    """The texels of ``zone`` on a trial's texture (its pixel grid from the texture's own size)."""
    per_mm = texture.values.shape[1] / texture.width_mm
    left, top = round(layout.zone_left_mm(zone) * per_mm), round(layout.gap_mm * per_mm)
    width, height = round(layout.zone_mm[0] * per_mm), round(layout.zone_mm[1] * per_mm)
    return texture.values[top + 1:top + height - 1, left + 1:left + width - 1].astype(float)


@pytest.mark.parametrize("task", ["staircase", "constant"])
def test_a_varied_stimulus_keeps_its_mean_at_every_level_as_the_check_rendered_it(task):
    # a sine grating at contrast c around mean 0.5 lies in 0.5 ± c/2 (by hand); it used to be rescaled to 1 - c..1
    stimuli = {"g": Stimulus("g", "grating-1mm", mean=0.5)}
    condition = Condition("c", "g", levels=(0.1, 0.25, 0.4), level_range=(0.05, 0.4))
    block = Block("b", task, ("c",), trials=8, repeats=1, intervals=2)
    recorder = Recorder()
    session = run(Design("mean", stimuli, {"c": condition}, (block,), seed=4), responder=recorder)
    assert len(recorder.shown) == len(plan(session.design)) and session.check.passed
    for shown in recorder.shown:
        target = zone_values(shown.texture(), shown.layout, shown.trial.target)
        assert target.mean() == pytest.approx(0.5, abs=0.003)
        assert target.max() - target.min() == pytest.approx(shown.level, abs=0.01)
        other = zone_values(shown.texture(), shown.layout, 1 - shown.trial.target)
        assert np.all(other == 1.0)  # the reference: plain glass
    checked = session.check.figures["g@0.4"]  # the top of the range, the largest level
    assert checked.asked_mean == pytest.approx(0.5, abs=0.003)  # what the check rendered is what trials play


def test_constant_stimuli_below_the_default_range_s_top_run_at_a_mean_that_range_would_not_fit():
    # levels 0.1 and 0.3 around 0.8 fit (0.8 ± 0.15); the default range's top, 0.6, would not, and is not used
    stimuli = {"g": Stimulus("g", "grating-1mm", mean=0.8)}
    condition = Condition("c", "g", levels=(0.1, 0.3))
    recorder = Recorder()
    session = run(Design("m", stimuli, {"c": condition}, (Block("b", "constant", ("c",), repeats=2),), seed=2),
                  responder=recorder)
    assert session.complete and len(recorder.shown) == 4
    for shown in recorder.shown:
        target = zone_values(shown.texture(), shown.layout, shown.trial.target)
        assert target.mean() == pytest.approx(0.8, abs=0.003)
        assert target.max() - target.min() == pytest.approx(shown.level, abs=0.01)


def test_an_adjustments_textures_from_the_stimulus_sampled_once_are_those_built_afresh_bit_for_bit():
    stimuli = {"ref": Stimulus("ref", "grating-2mm", contrast=0.2),
               "g": Stimulus("g", "grating-1mm", mean=0.6, scale=1.5, rotation_deg=30.0)}
    condition = Condition("c", "g", "ref", level_range=(0.05, 0.6))
    design = Design("adjust", stimuli, {"c": condition}, (Block("b", "adjustment", ("c",), repeats=1),), seed=1)
    recorder = Recorder()
    run(design, responder=recorder)
    shown = recorder.shown[0]
    layout, zone = shown.layout, design.zone_mm
    reference = zone_texture(stimuli["ref"], zone)
    for level in (0.6, 0.05, 0.2, shown.level, 0.2, 0.6 / 10 ** (1 / 20)):  # some again, in any order
        cached = shown.texture_at(level)
        adjusted = zone_texture(stimuli["g"], zone, level)  # loaded and sampled afresh, as every step used to be
        placements = [Placement(reference, layout.zone_left_mm(0), layout.gap_mm),
                      Placement(adjusted, layout.zone_left_mm(1), layout.gap_mm)]
        px = max(10.0, max(1.0 / min(p.texture.pixel_mm) for p in placements))
        fresh = compose(layout.size_mm, placements, 1.0, px_per_mm=min(px, 40.0), name=f"trial-{shown.trial.number}")
        assert cached.values.dtype == fresh.values.dtype and np.array_equal(cached.values, fresh.values)
        assert (cached.width_mm, cached.height_mm, cached.name) == (fresh.width_mm, fresh.height_mm, fresh.name)
        assert zone_values(cached, layout, 1).mean() == pytest.approx(0.6, abs=0.01)  # the mean kept at every level
