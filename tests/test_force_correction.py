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
