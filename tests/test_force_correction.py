"""The force correction: SETPOINTS_FORCE through the firmware core's binding (docs/protocol.md, "The force
correction"), and the host's side of it (the model's force exponent, the frame).

A host computes an amplitude at the normal force it measured 15-25 ms before the value plays; the device scales
the value by (F / F_h)^e with its own force F, e the model's d ln a / d ln F at F_h, capped at the smaller of the
host's and its own limit. Expectations are computed by hand here: from the numbers, and from the host model's
own inverse at the force the device measured (the stretched law's amplitude is exactly ∝ F^p)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware import sil
from ultraglide.render.physics.calibration import load_model

FS = 48000
PER_MS = FS // 1000
RATE = 12000
FULL_SCALE = 8.0  # µm p-p; the device's limit 6 µm: 0.75 of full scale
FORCE_SENSORS = p.SENSOR_AMPLITUDE | p.SENSOR_NORMAL_FORCE
V = 19660 / 65535  # 0.3 as its u16 code (0.3 x 65535 = 19660.5, ties to even)


class Device:
    """The bare core with force sensors: frames in, a millisecond of drive at a time, the force the test says."""

    def __init__(self, **settings):
        settings = {"sensors": FORCE_SENSORS, "features": p.FEATURE_FORCE_CORRECTION, **settings}
        self.core = sil.FirmwareCore(full_scale_um_pp=FULL_SCALE, max_amplitude_um_pp=6.0, **settings)
        self.seq = 0
        self.decoder = p.FrameDecoder()
        self.drive: list[np.ndarray] = []
        self.send(p.HELLO, p.hello_payload())

    def send(self, kind: int, payload: bytes = b"") -> list[p.Frame]:
        self.seq += 1
        self.core.receive(p.encode_frame(kind, self.seq, payload))
        return self.decoder.feed(self.core.transmit())

    def answer(self, kind: int, payload: bytes = b"") -> int | None:
        """The NAK reason of the one answer (None: accepted silently or acknowledged)."""
        naks = [f for f in self.send(kind, payload) if f.kind == p.NAK]
        return p.parse_nak(naks[0].payload)[1] if naks else None

    def force_frame(self, first: int, fractions, force_n: float, exponent: float, limit: float = 1.0) -> int | None:
        reference = p.ForceReference(force_n, exponent, limit)
        return self.answer(p.SETPOINTS_FORCE, p.setpoints_force_payload(first, RATE, np.asarray(fractions), reference))

    def run(self, ms: int, force_n: float = 0.5) -> np.ndarray:
        """``ms`` of drive, the force sensor reading ``force_n`` over each block; the last millisecond's drive."""
        for _ in range(ms):
            drive = self.core.render(PER_MS).copy()
            self.drive.append(drive)
            self.core.sense(np.full(PER_MS, 1.0, dtype=np.float32), np.full(PER_MS, force_n, dtype=np.float32))
        return self.drive[-1]


def enabled(**settings) -> Device:
    device = Device(**settings)
    assert device.answer(p.ENABLE, p.enable_payload(True)) is None
    return device


def test_a_value_is_scaled_by_the_force_measured_at_play_to_the_exponent_sent():
    device = enabled()
    assert device.force_frame(0, np.full(240, 0.3), force_n=0.5, exponent=1 / 3) is None
    device.run(11, force_n=0.6)  # prefill (10 ms), then playing: the drive follows the force of the block before
    assert device.run(1, force_n=0.6) == pytest.approx(np.full(PER_MS, V * 1.2 ** (1 / 3)), rel=2e-5)
    device.run(1, force_n=0.4)  # the press eases: less vibration for the same friction
    assert device.run(1, force_n=0.4) == pytest.approx(np.full(PER_MS, V * 0.8 ** (1 / 3)), rel=2e-5)
    assert device.run(1, force_n=0.5)[-1] == pytest.approx(V * 0.8 ** (1 / 3), rel=2e-5)  # the previous block's
    assert device.run(1, force_n=0.5) == pytest.approx(np.full(PER_MS, V), rel=2e-5)  # the host's force: as sent


def test_a_reading_beyond_half_or_twice_the_hosts_force_or_not_finite_plays_the_value_as_sent():
    device = enabled()
    device.force_frame(0, np.full(240, 0.3), force_n=0.5, exponent=1.0)
    device.run(11, force_n=0.5)
    for reading, expected in ((0.99, V * 0.99 / 0.5), (1.01, V), (0.26, V * 0.26 / 0.5), (0.24, V), (0.0, V),
                              (math.nan, V), (5.0, V)):
        device.run(1, force_n=reading)
        assert device.run(1, force_n=reading) == pytest.approx(np.full(PER_MS, expected), rel=2e-5), reading


def test_the_correction_stops_at_the_smaller_of_the_hosts_and_the_devices_limit():
    device = enabled()
    device.force_frame(0, np.full(120, 0.5), force_n=0.5, exponent=1.0, limit=0.6)  # 4.8 µm, the host's limit
    device.force_frame(120, np.full(120, 0.5), force_n=0.5, exponent=1.0, limit=1.0)  # the device's: 0.75
    device.run(1, force_n=0.9)  # playback starts at once (240 values buffered); 0.5 x 1.8 = 0.9 asked
    assert device.run(1, force_n=0.9) == pytest.approx(np.full(PER_MS, 0.6), abs=1e-4)  # 0.6 as a u16 code
    device.run(8, force_n=0.9)
    assert device.run(1, force_n=0.9) == pytest.approx(np.full(PER_MS, 0.75), rel=1e-6)
    assert max(d.max() for d in device.drive) <= 0.75 + 1e-7


def test_each_frames_values_carry_that_frames_reference_and_plain_setpoints_none():
    device = enabled()
    device.force_frame(0, np.full(120, 0.3), force_n=0.5, exponent=1.0)  # 10 ms at 12 kHz
    device.force_frame(120, np.full(120, 0.3), force_n=0.6, exponent=1.0)  # a newer measurement: 0.6 N
    device.answer(p.SETPOINTS, p.setpoints_payload(240, RATE, np.full(120, 0.3)))
    # 360 values buffered, more than the prefill: playback starts at once (the first block has no force yet)
    first, second, third = (np.concatenate([device.run(1, force_n=0.6) for _ in range(10)]) for _ in range(3))
    assert first[PER_MS:] == pytest.approx(np.full(9 * PER_MS, 1.2 * V), rel=2e-5)  # computed at 0.5 N: x 1.2
    assert second[PER_MS:] == pytest.approx(np.full(9 * PER_MS, V), rel=2e-5)  # computed at 0.6 N: as sent
    assert third[PER_MS:] == pytest.approx(np.full(9 * PER_MS, V), rel=2e-5)  # plain SETPOINTS: no correction
    assert device.core.status().setpoints == 360


@pytest.mark.parametrize("host_force, play_force", [(0.4, 0.55), (0.7, 0.45), (0.25, 0.3)])
def test_the_stretched_models_amplitude_at_the_force_of_the_play_is_what_plays(host_force, play_force):
    model = load_model("stretched")
    ratio = 0.5
    sent = float(model.amplitude_um_pp(np.array([ratio]), host_force).amplitude_um_pp[0])
    exponent = model.force_exponent  # a ∝ F^p: d ln a / d ln F = p, whatever the ratio
    assert exponent == pytest.approx(1 / 3)
    device = enabled()
    device.force_frame(0, np.full(240, sent / FULL_SCALE), force_n=host_force, exponent=exponent)
    device.run(11, force_n=play_force)
    played = device.run(1, force_n=play_force) * FULL_SCALE
    wanted = float(model.amplitude_um_pp(np.array([ratio]), play_force).amplitude_um_pp[0])
    assert played == pytest.approx(np.full(PER_MS, wanted), abs=2e-4)  # within a u16 code (1.2e-4 µm) and float32
    assert model.relative_friction(played[-1], play_force) == pytest.approx(ratio, abs=1e-4)


def test_refusals_follow_the_nak_order_and_change_nothing():
    plain = enabled(sensors=FORCE_SENSORS, features=0)  # no force correction
    assert plain.force_frame(0, np.full(12, 0.3), 0.5, 0.3) == p.NAK_UNSUPPORTED
    v2 = Device(max_version=2)
    assert v2.force_frame(0, np.full(12, 0.3), 0.5, 0.3) == p.NAK_UNSUPPORTED
    device = enabled()
    good = p.setpoints_force_payload(0, RATE, np.full(12, 0.3), p.ForceReference(0.5, 0.3, 1.0))
    assert device.answer(p.SETPOINTS_FORCE, good[:-1]) == p.NAK_BAD_LENGTH
    assert device.answer(p.SETPOINTS_FORCE, p.setpoints_payload(0, RATE, np.full(12, 0.3))) == p.NAK_BAD_LENGTH
    for force_n, exponent in ((0.0, 0.3), (-0.5, 0.3), (math.nan, 0.3), (math.inf, 0.3), (25.0, 0.3),
                              (0.5, 2.5), (0.5, -2.5), (0.5, math.nan)):
        assert device.force_frame(0, np.full(12, 0.3), force_n, exponent) == p.NAK_BAD_VALUE, (force_n, exponent)
    status = device.core.status()
    assert status.setpoints == 0 and status.buffered == 0 and status.stream_rate_hz == 0
    assert device.force_frame(0, np.full(12, 0.3), 20.0, 2.0) is None and device.core.status().setpoints == 12


def test_a_device_with_force_correction_needs_a_normal_force_sensor():
    with pytest.raises(Exception, match="refused its configuration"):
        sil.FirmwareCore(sensors=p.SENSOR_AMPLITUDE, features=p.FEATURE_FORCE_CORRECTION)


def test_the_framer_sends_the_bytes_of_the_plain_encoder_and_they_parse_back():
    framer = p.SetpointFramer(RATE)
    values = np.linspace(0, 0.7, 12)
    reference = p.ForceReference(0.43, 1 / 3, 0.75)
    wire = framer.frame(9, 1234, values, reference)
    assert wire == p.encode_frame(p.SETPOINTS_FORCE, 9, p.setpoints_force_payload(1234, RATE, values, reference))
    frame = p.FrameDecoder().feed(wire)[0]
    first, rate, back, fractions = p.parse_setpoints_force(frame.payload)
    assert (first, rate) == (1234, RATE) and fractions == pytest.approx(values, abs=1 / 65535)
    assert back.force_n == pytest.approx(0.43) and back.exponent == pytest.approx(1 / 3)
    assert back.limit_fraction == pytest.approx(0.75, abs=1 / 65535)
    assert framer.frame(9, 1234, values) == p.encode_frame(p.SETPOINTS, 9, p.setpoints_payload(1234, RATE, values))



@settings(max_examples=60, deadline=None)
@given(q_factor=st.sampled_from([0.5, 1.0, 2.0]), loop=st.booleans(), host_limit=st.floats(0.2, 1.0),
       frames=st.lists(st.tuples(st.floats(0.0, 1.0), st.floats(0.05, 20.0), st.floats(-2.0, 2.0), st.booleans()),
                       min_size=1, max_size=30),
       forces=st.lists(st.one_of(st.floats(0.0, 60.0), st.just(math.nan)), min_size=1, max_size=30))
def test_whatever_the_references_and_the_forces_the_plate_stays_within_the_limits(q_factor, loop, host_limit, frames,
                                                                                  forces):
    """Corrected values never drive the plate (up to twice as fast as configured) above the device's limit, and
    in open loop without overdrive the drive never goes above the host's limit either."""
    device = Device(features=p.FEATURE_FORCE_CORRECTION | p.FEATURE_AMPLITUDE_LOOP)
    if loop:
        assert device.answer(p.SET_LOOP, p.set_loop_payload(1)) is None
    assert device.answer(p.ENABLE, p.enable_payload(True)) is None
    alpha = math.exp(-1.0 / (FS * q_factor * 200.0 / (math.pi * 25000.0)))
    plate, index, host_code = 0.0, 0, math.floor(host_limit * 65535) / 65535
    for k, (value, force_n, exponent, with_force) in enumerate(frames):
        values = np.full(12, min(value, host_code))  # the host's own values are within its limit
        if with_force:
            device.force_frame(index, values, force_n, exponent, host_code)
        else:
            device.answer(p.SETPOINTS, p.setpoints_payload(index, RATE, values))
        index += 12
        for _ in range(2):
            drive = device.core.render(PER_MS).copy()
            amplitude, _ = lfilter([(1 - alpha) * FULL_SCALE], [1, -alpha], drive, zi=[alpha * plate])
            plate = float(amplitude[-1])
            assert amplitude.max() <= 6.0 * (1 + 1e-4)
            if not loop:  # open loop, the limit's share is the ceiling (no overdrive configured)
                assert drive.max() <= max(host_code, values.max()) + 1e-6
            device.core.sense(amplitude.astype(np.float32), np.full(PER_MS, forces[k % len(forces)], dtype=np.float32))


# ---- the host's side: the exponent its model gives, the reference its inverse leaves ----

def test_the_force_exponent_is_what_each_models_inverse_gives():
    from ultraglide.render.engine.friction_controller import force_exponent
    from ultraglide.render.physics.empirical_models import StretchedExponentialModel

    stretched = load_model("stretched")  # s(F) = s0 (F / 0.5 N)^(1/3): a ∝ F^(1/3) at every ratio
    for ratio in (0.3, 0.5, 0.9):
        for force in (0.2, 0.5, 1.0):
            assert force_exponent(stretched, ratio, force) == pytest.approx(1 / 3, abs=1e-9)
    assert force_exponent(StretchedExponentialModel(force_exponent=0.6), 0.5, 0.4) == pytest.approx(0.6, abs=1e-9)
    paper = load_model("paper")  # the detachment amplitude 2F/k_n with A ∝ F^(2/3): F^(1/3) below saturation
    assert force_exponent(paper, 0.85, 0.5) == pytest.approx(1 / 3, abs=1e-3)
    assert force_exponent(load_model("exponential"), 0.5, 0.5) == 0.0  # Monnoyer's law has no force in it
    assert force_exponent(stretched, 1.0, 0.5) == 0.0  # no vibration asked: nothing to scale
    # one step of the exponent is the inverse at the new force: a(F') = a(F) (F'/F)^e
    a = lambda force: float(stretched.amplitude_um_pp(np.array([0.5]), force).amplitude_um_pp[0])  # noqa: E731
    assert a(0.62) == pytest.approx(a(0.4) * (0.62 / 0.4) ** force_exponent(stretched, 0.5, 0.4), rel=1e-9)


def test_one_amplitude_is_the_array_inverses_to_the_bit():
    """The scalar inverse the force exponent uses is the array inverse's value exactly, for the stretched family and
    a table (the paper's), at the limit and the floor."""
    from ultraglide.render.physics.empirical_models import StretchedExponentialModel

    rng = np.random.default_rng(5)
    ratios = np.concatenate((rng.uniform(0.0, 1.0, 300), [0.0, 0.1, 0.5, 1.0, 1.5]))
    for model in (load_model("stretched"), load_model("exponential"), load_model("paper"),
                  StretchedExponentialModel(3.0, 1.7, 0.5, residual_ratio=0.1)):
        for force in (0.2, 0.5, 1.3):
            for limit in (np.inf, 6.0, 1.0):
                expected = model.amplitude_um_pp(ratios, force, limit).amplitude_um_pp
                assert [model.one_amplitude_um_pp(r, force, limit) for r in ratios.tolist()] == expected.tolist()


def test_the_inverse_leaves_its_force_and_exponent_only_while_it_follows():
    from ultraglide.render.engine.friction_controller import ClosedLoopInverse, ControllerSettings, LoopCommand

    now = [10.0]
    inverse = ClosedLoopInverse(load_model("stretched"), ControllerSettings(blend_s=0.05), clock=lambda: now[0])
    ratio = np.full(12, 0.5)
    inverse.amplitude_um_pp(ratio, 0.5, 6.0)
    assert inverse.force_reference is None  # open loop: the renderer's force, nothing to correct
    inverse.command = LoopCommand(True, 1.2, 0.42, 10.0, 10.0, "closed loop: following")
    now[0] = 10.02
    inverse.amplitude_um_pp(ratio, 0.5, 6.0)
    assert inverse.force_reference is None  # blending from the open-loop amplitude (computed at another force)
    now[0] = 10.06
    inverse.amplitude_um_pp(ratio, 0.5, 6.0)
    assert inverse.force_reference == (0.42, pytest.approx(1 / 3))
    now[0] = 10.3  # the sensors silent for 300 ms: open loop, no reference
    inverse.amplitude_um_pp(ratio, 0.5, 6.0)
    assert inverse.force_reference is None


# ---- in the simulated rig: the firmware core, the plate, the finger, the host's loop ----

def _step_settling(q: float | None, force_correction: bool) -> tuple[np.ndarray, object]:
    import sys

    from conftest import ROOT

    sys.path.insert(0, str(ROOT / "bench"))
    from bench_closed_loop import LEARN_S, SETTLE_WINDOW_S
    from closed_loop_rig import ClosedLoopRig
    from ultraglide.textures.texture import Texture

    x = np.arange(800) * 0.1  # 40 mm: 1 for the first 20, 0.5 for the next (the bench's stripes)
    stripes = np.where((x % 40.0) < 20.0, 1.0, 0.5)[None, :].repeat(100, axis=0).astype(np.float32)
    texture = Texture(stripes, 80.0, 10.0, name="steps", outside="tile")
    run = ClosedLoopRig(texture, 100.0, True, q=q, log_hz=12000.0, seconds=6.0,
                        force_correction=force_correction).run(6.0)
    t, target = run.t, run.target
    start = t[run.pick(0.0)][0] + LEARN_S
    per_second = len(t) / (t[-1] - t[0])
    steps = np.flatnonzero((target[1:] < 0.75) & (target[:-1] >= 0.75) & (t[1:] > start)) + 1
    settling = []
    for k in steps:  # from the step until the finger's ratio stays within 0.05 of 0.5 (to 50 ms after it)
        window = slice(k, k + int(SETTLE_WINDOW_S * per_second))
        outside = np.flatnonzero(np.abs(run.ratio[window] - 0.5) > 0.05)
        settling.append((t[window][outside[-1]] - t[k] + 1 / per_second) if len(outside) else 0.0)
    return np.array(settling), run


@pytest.mark.slow
def test_steps_settle_within_10_ms_with_the_force_corrected_in_the_firmware():
    settling, run = _step_settling(None, True)
    assert len(settling) >= 8 and settling.max() <= 0.010, settling
    assert run.peak_um_pp <= 6.0 and np.nanmax(run.commanded) <= 6.0  # the plate never above its limit
    uncorrected, _ = _step_settling(None, False)  # the same run with the force 15-25 ms old when it plays
    assert uncorrected.max() > 0.010, uncorrected


@pytest.mark.slow
def test_on_a_plate_of_twice_the_profiles_q_steps_settle_within_10_ms_too():
    settling, run = _step_settling(400.0, True)  # its decays twice as long: the fast correction once ran high here
    assert len(settling) >= 8 and settling.max() <= 0.010, settling
    assert run.peak_um_pp <= 6.0
