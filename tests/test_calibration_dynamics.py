"""The friction dynamics fitted from a calibration's edges (render/physics/dynamics_fit.py), on synthetic recordings.

Each recording is made here independently of the fitter: the finger's ratio stepped through a law, lagged sample
by sample at 48 kHz (onset and recovery time constants chosen per direction, as measured fingers do), passed through
a first-order low-pass and a pure delay (the force sensors), then averaged over each millisecond as a device's
SENSORS sample is. The fitter must find the time constants the recording was made with, and must not take the
sensors' lag for the finger's."""

import math
import tomllib

import numpy as np
import pytest
from conftest import assert_one_line_error
from numba import njit
from ultraglide.render.physics.calibration import calibration_toml, fit_model, read_calibration
from ultraglide.render.physics.dynamics import DynamicFrictionModel, FrictionDynamics
from ultraglide.render.physics.dynamics_fit import (
    Recording,
    SensorLag,
    edge_course,
    find_steps,
    fit_dynamics,
    read_recording,
    recording_from_text,
    step_points,
)
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.friction_models import ExponentialModel

RATE = 48000  # the synthetic plate's samples a second
SENSOR_HZ = 1000
LAW = ExponentialModel()  # exp(-a^2 / (2 tau^2)), tau = 1.32 µm zero-to-peak


def synthetic(onset_s, recovery_s, bandwidth_hz=300.0, delay_s=0.001, rise_s=0.0, speeds=(100.0,), exponent=0.5,
              reference=100.0, noise=0.0, steps=8, seed=0):
    """A recording of reduced steps (120 ms on, 120 ms rest, amplitudes 1.0-5.2 µm p-p) at 0.5 N, each at one of
    ``speeds`` in turn (the recovery's time constant recovery_s (reference / v)^exponent), made at 48 kHz: the
    plate's amplitude rising first order (``rise_s``), the finger's lag, the sensors, 1 ms means."""
    ms = 100 + steps * 240 + 150
    t = np.arange(ms * RATE // 1000) / RATE
    amplitude = np.zeros_like(t)
    speed = np.full_like(t, speeds[0])
    for k in range(steps):
        start = 0.1 + 0.24 * k
        amplitude[(t >= start) & (t < start + 0.12)] = 1.0 + 0.6 * (k % 8)
        speed[(t >= start) & (t < start + 0.24)] = speeds[k % len(speeds)]
    if rise_s:
        _low_pass(amplitude, math.exp(-1.0 / (RATE * rise_s)))  # the plate's resonator rising and decaying
    static = LAW.relative_friction(amplitude, 0.5)
    fall = math.exp(-1.0 / (RATE * onset_s)) if onset_s else 0.0
    taus = recovery_s * (reference / speed) ** exponent
    rises = np.exp(-1.0 / (RATE * np.maximum(taus, 1e-12)))
    felt = _lagged(static, fall, rises)
    sensed = felt.copy()
    if bandwidth_hz:
        _low_pass(sensed, math.exp(-2 * math.pi * bandwidth_hz / RATE))
    shift = round(delay_s * RATE)
    sensed = np.concatenate((np.full(shift, sensed[0]), sensed[:len(sensed) - shift]))
    per = RATE // SENSOR_HZ
    mu = 0.8 * sensed.reshape(-1, per).mean(axis=1)  # mu0 0.8
    mu += np.random.default_rng(seed).normal(0.0, noise, len(mu))
    mean_amplitude = amplitude.reshape(-1, per).mean(axis=1)
    one_speed = speeds[0] if len(speeds) == 1 else math.nan
    return Recording(np.arange(ms) / SENSOR_HZ, mean_amplitude, np.full(ms, 0.5), 0.5 * mu,
                     SensorLag(SENSOR_HZ, bandwidth_hz, delay_s, "synthetic"), one_speed)


@njit(cache=True)
def _low_pass(x, alpha):
    """In place: y[i] = alpha y[i-1] + (1 - alpha) x[i], from y settled on x[0]."""
    state = x[0]
    for i in range(x.shape[0]):
        state = alpha * state + (1.0 - alpha) * x[i]
        x[i] = state


@njit(cache=True)
def _lagged(static, fall, rises):
    """The finger's lag: falling with keep ``fall`` a sample, rising with ``rises[i]``."""
    out = np.empty_like(static)
    value = static[0]
    for i in range(static.shape[0]):
        s = static[i]
        keep = fall if s < value else rises[i]
        value = s + (value - s) * keep
        out[i] = value
    return out


def fitted(recording, speeds=None, samples=100):
    steps = find_steps(recording)
    if speeds is not None:  # each step's edges at its own speed
        from dataclasses import replace
        steps = [replace(s, onset=replace(s.onset, speed_mm_s=speeds[s.number % len(speeds)]),
                         recovery=replace(s.recovery, speed_mm_s=speeds[s.number % len(speeds)])) for s in steps]
    return steps, fit_dynamics(recording, steps, LAW, samples=samples)


def test_a_first_order_step_through_the_sensors_as_worked_by_hand():
    """5 ms lag, sensors without filter 2 ms late: the step at sample 20 shows from sample 22, and at the middle of
    sample 22 + k the ratio has fallen to exp(-(k + 1/2) / 5); a 300 Hz filter delays it further."""
    step = np.r_[np.ones(20), np.zeros(40)]
    course = edge_course(step, 0.005, SensorLag(1000.0, 0.0, 0.002))
    assert course[:22].tolist() == [1.0] * 22
    assert course[22:26] == pytest.approx(np.exp(-(np.arange(4) + 0.5) / 5.0), abs=1e-12)
    filtered = edge_course(step, 0.005, SensorLag(1000.0, 300.0, 0.002))
    assert np.all(filtered[22:40] > course[22:40])


def test_the_time_constants_the_recording_was_made_with_are_found():
    """No plate rise, no noise: onset 5 ms and recovery 33 ms through 300 Hz sensors 1 ms late come back within
    0.15 ms and 1 % (the model's 8x oversampling of each millisecond's mean)."""
    steps, fit = fitted(synthetic(0.005, 0.033))
    assert len(steps) == 8
    assert fit.onset.resolved and fit.recovery.resolved
    assert fit.onset.fitted_s == pytest.approx(0.005, abs=0.00015)
    assert fit.recovery.fitted_s == pytest.approx(0.033, rel=0.01)
    assert fit.dynamics == FrictionDynamics(fit.onset.fitted_s, fit.recovery.fitted_s, 100.0, 0.5)
    assert "kept as assumed" in fit.speed_exponent_note and "all at 100 mm/s" in fit.speed_exponent_note


def test_a_rising_plate_is_the_plates_and_noise_gives_an_interval_around_the_truth():
    """The plate rising over 1 ms (known only as each millisecond's mean) and 0.004 of noise on mu: within a fifth
    of a sample period (0.2 ms) for the onset, 2 % for the recovery. The bootstrap interval is the edges' spread
    (the noise's), around the fit; the sampling's own bias (about 0.05 ms here) is not in it."""
    _, fit = fitted(synthetic(0.005, 0.033, rise_s=0.001, noise=0.004, steps=16))
    assert fit.onset.fitted_s == pytest.approx(0.005, abs=0.0002)
    assert fit.onset.low_s < fit.onset.fitted_s < fit.onset.high_s
    assert fit.recovery.fitted_s == pytest.approx(0.033, rel=0.02)
    assert fit.recovery.low_s < 0.033 < fit.recovery.high_s
    assert 0 < fit.onset.stderr_s < 0.0005


def test_the_sensors_lag_is_not_taken_for_the_fingers():
    """An instantaneous finger behind slow sensors (50 Hz, 4 ms late): with the sensors modelled, neither time
    constant is resolved and no dynamics are claimed; modelled as instantaneous sensors, the same data would give a
    3 ms lag (the sensors' own 1 / (2 pi 50 Hz) = 3.2 ms)."""
    recording = synthetic(0.0, 0.0, bandwidth_hz=50.0, delay_s=0.004)
    _, fit = fitted(recording)
    assert not fit.onset.resolved and not fit.recovery.resolved and fit.dynamics is None
    assert "cannot be told from instantaneous" in fit.onset.note and "published 5 ms kept" in fit.onset.note
    assert fit.lag.resolution_s == pytest.approx(1 / (2 * math.pi * 50.0))
    blind = Recording(recording.t_s, recording.amplitude_um_pp, recording.normal_force_n, recording.lateral_force_n,
                      SensorLag(1000.0, 0.0, 0.004, "no filter"), 100.0)
    _, wrong = fitted(blind)
    assert wrong.onset.fitted_s == pytest.approx(1 / (2 * math.pi * 50.0), rel=0.25)


def test_a_lag_shorter_than_a_sample_is_not_claimed():
    _, fit = fitted(synthetic(0.0003, 0.0003))
    assert fit.dynamics is None and fit.onset.high_s < 0.001 and fit.recovery.high_s < 0.001


def test_the_recoverys_speed_law_is_fitted_only_over_speeds_that_span():
    """Edges at 25, 50, 100 and 200 mm/s with the recovery 30 ms (100 / v)^0.8: the exponent within 0.1, stated at
    the speeds' geometric mean (70.7 mm/s), 30 ms at 100 mm/s and 30 x 4^0.8 = 91 ms at 25 mm/s within 5 %."""
    speeds = (25.0, 50.0, 100.0, 200.0)
    _, fit = fitted(synthetic(0.005, 0.030, speeds=speeds, exponent=0.8, steps=16), speeds=speeds)
    assert fit.speed_exponent == pytest.approx(0.8, abs=0.1)
    assert fit.reference_speed_mm_s == pytest.approx(math.sqrt(25.0 * 200.0))
    assert fit.dynamics.recovery_at_s(100.0) == pytest.approx(0.030, rel=0.05)
    assert fit.dynamics.recovery_at_s(25.0) == pytest.approx(0.030 * 4 ** 0.8, rel=0.05)
    assert "speed law fitted" in fit.speed_exponent_note


def test_without_a_known_speed_the_recovery_is_reported_not_used():
    recording = synthetic(0.005, 0.033)
    unknown = Recording(recording.t_s, recording.amplitude_um_pp, recording.normal_force_n,
                        recording.lateral_force_n, recording.lag, math.nan)
    _, fit = fitted(unknown)
    assert fit.recovery.fitted_s == pytest.approx(0.033, rel=0.01) and not fit.recovery.resolved
    assert fit.dynamics.recovery_s == 0.070 and fit.dynamics.reference_speed_mm_s == 22.0  # the published
    assert "not known" in fit.recovery.note
    assert fit.dynamics.source == "onset fitted on the plate, 8 edges, recovery published"


def test_the_calibration_file_keeps_the_dynamics_and_reads_back_dynamic(tmp_path):
    recording = synthetic(0.005, 0.033)
    steps, dynamics = fitted(recording)
    fit = fit_model(step_points(steps, "synthetic"), "exponential")
    path = tmp_path / "cal.toml"
    path.write_text(calibration_toml(fit, participant="P1", dynamics=dynamics, recording="cal-recording.csv"))
    table = tomllib.loads(path.read_text())["dynamics"]
    assert table["fitted"] is True and table["source"] == "fitted on the plate, 16 edges (8 onsets, 8 recoveries)"
    assert table["onset"]["range_s"][0] < table["onset_s"] < table["onset"]["range_s"][1]
    model = read_calibration(path)
    assert isinstance(model, DynamicFrictionModel) and model.dynamics == dynamics.dynamics
    assert model.static.parameters() == fit.model.parameters()
    assert "(fitted on the plate, 16 edges (8 onsets, 8 recoveries))" in model.describe()
    static = fit_model(step_points(steps, "synthetic"), "exponential")
    _, none = fitted(synthetic(0.0, 0.0))
    path.write_text(calibration_toml(static, dynamics=none))
    assert tomllib.loads(path.read_text())["dynamics"]["fitted"] is False
    assert type(read_calibration(path)).__name__ == "ExponentialModel"  # as a file without [dynamics] reads


@pytest.mark.parametrize("table, words", [
    ("fitted = 1", "fitted = true or false"),
    ("fitted = true\nonset_s = 0.005\nrecovery_s = 0.03\nreference_speed_mm_s = 100.0", "speed_exponent must be"),
    ("fitted = true\nonset_s = 5.0\nrecovery_s = 0.03\nreference_speed_mm_s = 100.0\nspeed_exponent = 0.5",
     "the onset time constant must lie in"),
])
def test_a_calibration_files_bad_dynamics_are_refused_in_one_line(tmp_path, table, words):
    path = tmp_path / "cal.toml"
    path.write_text(f'ultraglide_calibration = 1\nmodel = "exponential"\n[parameters]\ntau_um_zp = 1.3\n'
                    f'[dynamics]\n{table}\n')
    with pytest.raises(ModelError, match=words) as error:
        read_calibration(path)
    assert str(path) in str(error.value) and "\n" not in str(error.value)


def test_a_recording_reads_back_as_written(tmp_path):
    recording = synthetic(0.005, 0.033, steps=2)
    path = tmp_path / "rec.csv"
    path.write_text(recording.text())
    back = read_recording(path)
    assert back.lag == recording.lag and back.speed_mm_s == 100.0
    assert back.lateral_force_n == pytest.approx(recording.lateral_force_n, abs=1e-6)
    assert back.t_s == pytest.approx(recording.t_s)


@pytest.mark.parametrize("text, words", [
    ("t_s,amplitude_um_pp,normal_force_n,lateral_force_n\n0,0,0.5,0.4\n", "not an ultraglide recording"),
    ("# ultraglide_recording = 1\n# sensor_rate_hz = 1000\n# sensor_bandwidth_hz = 300\n# sensor_delay_s = 0.001\n"
     "# sliding_speed_mm_s = 100\nt_s,amplitude_um_pp,normal_force_n,lateral_force_n\n0,0,0.5\n", "line 7: four"),
    ("# ultraglide_recording = 1\n# sensor_rate_hz = 0\nt_s,amplitude_um_pp,normal_force_n,lateral_force_n\n",
     "sensor_rate_hz must lie in"),
    ("# ultraglide_recording = 1\n# sensor_rate_hz = 1000\n# sensor_bandwidth_hz = 300\n# sensor_delay_s = 0.001\n"
     "# sliding_speed_mm_s = 100\nt_s,amplitude_um_pp,normal_force_n,lateral_force_n\n0.001,0,0.5,0.4\n"
     "0.001,0,0.5,0.4\n", "strictly increasing"),
])
def test_a_bad_recording_is_refused_with_what_is_wrong(text, words):
    with pytest.raises(ModelError, match=words):
        recording_from_text(text, "rec.csv")


def test_calibrate_on_a_recording_without_compare_says_what_to_do(cli, tmp_path):
    path = tmp_path / "rec.csv"
    path.write_text(synthetic(0.005, 0.033, steps=2).text())
    line = assert_one_line_error(cli("calibrate", path))
    assert "--compare" in line
    line = assert_one_line_error(cli("calibrate", path, "--compare", "-o", tmp_path / "x.toml"))
    assert "writes nothing" in line
    broken = tmp_path / "broken.csv"
    broken.write_text("# ultraglide_recording = 1\n# sensor_rate_hz = 1000\nnot,a,header\n")
    assert "the header must be" in assert_one_line_error(cli("calibrate", broken, "--compare"))


def test_a_calibration_whose_recording_cannot_be_written_is_refused_before_the_session(cli, tmp_path):
    (tmp_path / "p1-recording.csv").mkdir()
    line = assert_one_line_error(cli("calibrate", "--device", "sim", "--participant", "P1", "-o", tmp_path / "p1.toml",
                                     "--no-window", "--forces", "0.5", "--passes", "1"))
    assert "its recording beside it" in line and "is a directory" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p1-recording.csv"]  # nothing written


def test_a_real_plates_sensor_options_are_refused_on_the_simulator(cli, tmp_path):
    line = assert_one_line_error(cli("calibrate", "--device", "sim", "--participant", "P1", "-o", tmp_path / "p1.toml",
                                     "--no-window", "--sensor-delay-ms", "2"))
    assert "--finger-delay-ms" in line
