"""The simulated finger's friction in time (devices/sim/finger.py): the plate's own lag of its law, against the
first-order step response, and the options that ask for it."""

import math

import numpy as np
import pytest
from ultraglide.apps.cli.parser import build_parser
from ultraglide.apps.commands.finger_options import finger_config
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.sim.finger import FingerDynamics, FingerParams, ForceScript, SimulatedFinger
from ultraglide.devices.sim.force_sensors import ForceSensorParams
from ultraglide.render.engine.finger_setup import FingerConfig, build_finger

FS = 48000
STILL = FingerParams(drift=0.0, moisture=0.0)
IDEAL = ForceSensorParams(noise_n=0.0, bandwidth_hz=0.0, delay_s=0.0)


def law(amplitude, force):
    return np.where(np.asarray(amplitude) > 1.0, 0.2, 1.0)  # 0.2 with the vibration on, 1 without




def felt(finger: SimulatedFinger, amplitude: np.ndarray, chunk: int = 480) -> np.ndarray:
    """The finger's true friction ratio over ``amplitude``, chunk by chunk (the state carries over)."""
    out = []
    for k in range(0, len(amplitude), chunk):
        t = (k + np.arange(min(chunk, len(amplitude) - k))) / FS
        out.append(finger.truth(t, amplitude[k:k + chunk]).relative_friction)
    return np.concatenate(out)


def test_the_finger_falls_in_the_onset_time_and_recovers_in_the_recovery_time():
    speed = 22.0
    finger = SimulatedFinger(law, ForceScript.constant(0.5, speed), STILL, IDEAL, dynamics=FingerDynamics())
    on = int(0.2 * FS)
    amplitude = np.r_[np.full(on, 4.0), np.zeros(int(0.4 * FS))]
    ratio = felt(finger, amplitude)
    tau_on = int(round(0.005 * FS))
    # sample i is the ratio after i + 1 samples of the step: 1 - 0.8 (1 - e^-1) at 5 ms
    assert ratio[tau_on - 1] == pytest.approx(1.0 - 0.8 * (1 - math.exp(-1.0)), rel=1e-9)
    assert ratio[on - 1] == pytest.approx(0.2, abs=1e-9)  # settled after 40 onsets
    tau_back = int(round(0.070 * FS))
    assert ratio[on + tau_back - 1] == pytest.approx(0.2 + 0.8 * (1 - math.exp(-1.0)), rel=1e-9)


def test_the_recovery_is_slower_when_sliding_slower_and_a_lift_resets_it():
    slow = SimulatedFinger(law, ForceScript.constant(0.5, 5.5), STILL, IDEAL, dynamics=FingerDynamics())
    back = felt(slow, np.r_[np.full(FS // 10, 4.0), np.zeros(FS // 10)])
    # (22 / 5.5)^0.5 = 2: a 140 ms recovery; 100 ms into it, 0.2 + 0.8 (1 - e^(-100/140))
    assert back[-1] == pytest.approx(0.2 + 0.8 * (1 - math.exp(-100 / 140)), rel=1e-6)
    without = SimulatedFinger(law, ForceScript.constant(0.5, 5.5), STILL, IDEAL)
    assert felt(without, np.full(10, 4.0)).tolist() == [0.2] * 10  # no dynamics: the law at once


@pytest.mark.parametrize("field, value", [("onset_s", 0.0), ("recovery_s", 2.0), ("speed_exponent", math.inf)])
def test_finger_dynamics_outside_their_range_are_refused(field, value):
    with pytest.raises(DeviceError, match="must lie in"):
        FingerDynamics(**{field: value})


def test_plate_sim_finger_dynamics_option_builds_a_lagging_finger():
    parser = build_parser()
    args = parser.parse_args(["plate-sim", "--finger", "exponential", "--finger-dynamics"])
    config = finger_config(args)
    assert config.lags and "friction in time" in config.law_words()
    assert build_finger(config).dynamics == FingerDynamics()
    assert build_finger(FingerConfig(law="dynamic")).dynamics == FingerDynamics()  # a dynamic law lags
    assert build_finger(FingerConfig()).dynamics == FingerDynamics()  # the default finger lags, as real ones do
    assert build_finger(FingerConfig(law="exponential")).dynamics is None  # another law follows at once
    unlagged = finger_config(parser.parse_args(["plate-sim", "--no-finger-dynamics"]))
    assert not unlagged.lags and build_finger(unlagged).dynamics is None


def test_a_finger_whose_law_is_a_calibration_lags_as_its_fitted_dynamics_say(tmp_path):
    """A calibration fitted on the plate (its [dynamics] fitted = true) describes that finger in time too: the
    simulated finger given it lags with those time constants, without --finger-dynamics; one without fitted
    dynamics follows its law at once."""
    fitted = tmp_path / "p01.toml"
    fitted.write_text('ultraglide_calibration = 1\nmodel = "exponential"\n[parameters]\ntau_um_zp = 1.3\n'
                      '[dynamics]\nfitted = true\nonset_s = 0.01\nrecovery_s = 0.05\nreference_speed_mm_s = 100.0\n'
                      'speed_exponent = 0.5\n')
    finger = build_finger(FingerConfig(law=str(fitted), speed_mm_s=25.0, force="0.5", drift=0.0, moisture=0.0,
                                       noise_n=0.0))
    assert finger.dynamics == FingerDynamics(0.01, 0.05, 100.0, 0.5)
    assert FingerConfig(law=str(fitted)).lags and "friction in time" in finger.name
    # the words say whose lag: the fit's time constants, not the published 5 and 70 ms
    assert "friction in time (10 ms down, 50 ms back at 100 mm/s (x (v_ref/v)^0.5))" in finger.name
    assert "(5 ms down, 70 ms back at 22 mm/s" in FingerConfig(law="exponential", dynamics=True).law_words()
    static = tmp_path / "static.toml"
    static.write_text('ultraglide_calibration = 1\nmodel = "exponential"\n[parameters]\ntau_um_zp = 1.3\n'
                      '[dynamics]\nfitted = false\n')
    assert build_finger(FingerConfig(law=str(static))).dynamics is None
    # its truth: a step of the vibration on and off at 25 mm/s, the recovery (100/25)^0.5 = 2 times 50 ms
    on = int(0.1 * FS)
    amplitude = np.r_[np.full(on, 6.0), np.zeros(int(0.3 * FS))]
    ratio = felt(finger, amplitude)
    low = float(np.exp(-(3.0 / 1.3) ** 2 / 2.0))  # the exponential law at 6 µm p-p: exp(-a²/2tau²), a zero-to-peak
    tau_on = int(round(0.01 * FS))
    assert ratio[tau_on - 1] == pytest.approx(1.0 - (1.0 - low) * (1 - math.exp(-1.0)), rel=1e-6)
    tau_back = int(round(0.1 * FS))
    start = ratio[on - 1]
    assert ratio[on + tau_back - 1] == pytest.approx(start + (1.0 - start) * (1 - math.exp(-1.0)), rel=1e-6)
