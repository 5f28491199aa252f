"""What the engine's process opens: the simulated finger it puts on ``sim`` for a closed loop nobody gave one."""

import pytest
from ultraglide.devices.sim.finger import FingerDynamics
from ultraglide.render.engine import EngineConfig
from ultraglide.render.engine.finger_setup import FingerConfig
from ultraglide.render.engine.parts import load_parts
from ultraglide.render.engine.serving import close_device


def opened_finger(**config):
    _, model, _, device = load_parts(EngineConfig(texture="grating-1mm", device="sim", closed_loop=True, **config))
    try:
        return model, device.finger
    finally:
        assert close_device(device) is None


@pytest.mark.parametrize("name", ["stretched", "exponential"])
def test_a_static_models_loop_gets_a_finger_without_lag(name):
    """A static model cannot know of lag: its loop would read a lagging finger's slow recovery as a slipperier
    finger and never find its sensors' timing, so the finger given it follows its law at once."""
    model, finger = opened_finger(model=name)
    assert getattr(model, "dynamics", None) is None
    assert finger is not None and finger.dynamics is None


def test_a_dynamic_models_loop_gets_the_published_lag():
    model, finger = opened_finger(model="dynamic")
    assert model.dynamics is not None
    assert finger.dynamics == FingerDynamics()


def test_a_finger_asked_for_is_the_one_given_whatever_the_model():
    _, lagging = opened_finger(model="stretched", finger=FingerConfig(dynamics=True))
    assert lagging.dynamics == FingerDynamics()
    _, unlagged = opened_finger(model="dynamic", finger=FingerConfig(dynamics=False))
    assert unlagged.dynamics is None


def test_the_default_finger_from_play_follows_the_model_unless_its_lag_is_named():
    """``play --closed-loop --model stretched`` on sim: the finger play builds from its options (the default law,
    lag not named) is the default finger, so it follows the static model's assumption; a law of its own keeps its
    own way."""
    _, default = opened_finger(model="stretched", finger=FingerConfig(force="0.5"))
    assert default.dynamics is None
    _, dynamic_law = opened_finger(model="stretched", finger=FingerConfig(law="dynamic"))
    assert dynamic_law.dynamics == FingerDynamics()
