"""Effects attached to a sprite (``effects.attach``): they play while the finger is on the sprite and stop when it
leaves, in the engine's envelope record: the effect's modulation (its depth and frequency, as the effect defines
them) present under the finger on the sprite and absent off it."""

import json
import time

import numpy as np
import pytest
from service_run import flat_png, hold, png_ratio, read_envelope, rows_at, running_service
from ultraglide.textures import effects

from ultraglide.client import BadMessage, Client, EngineRefused, Unknown


def slide(client, points, seconds=0.3):
    """One finger down at the first point, held ``seconds`` at each point in turn (a move every 10 ms), lifted."""
    client.touch(*points[0], "down")
    for point in points:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            time.sleep(0.01)
            client.touch(*point, "move")
    client.touch(*points[-1], "up")


def modulation(rows):
    """(peak-to-peak of the target ratio, its strongest frequency in Hz) over rows of the envelope record."""
    t, ratio = rows["t_s"], rows["target_ratio"]
    grid = np.arange(t[0], t[-1], 1e-3)
    signal = np.interp(grid, t, ratio)
    spectrum = np.abs(np.fft.rfft(signal - signal.mean()))
    frequencies = np.fft.rfftfreq(len(grid), 1e-3)
    return float(np.ptp(ratio)), float(frequencies[np.argmax(spectrum)])


def settled(rows, after_s=0.06):
    """The rows from ``after_s`` after the first (the release of an effect, the composition before a change)."""
    return rows[rows["t_s"] > rows["t_s"][0] + after_s]


def test_an_attached_effect_plays_on_its_sprite_and_stops_off_it(tmp_path):
    # an AHAP continuous event: a 50 Hz modulation (sharpness 0) of depth 0.4 (intensity) for 20 s
    ahap = tmp_path / "buzz.ahap"
    ahap.write_text(json.dumps({"Version": 1.0, "Pattern": [{"Event": {
        "Time": 0.0, "EventType": "HapticContinuous", "EventDuration": 20.0,
        "EventParameters": [{"ParameterID": "HapticIntensity", "ParameterValue": 0.4},
                            {"ParameterID": "HapticSharpness", "ParameterValue": 0.0}]}}]}))
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            plate.set_view("main", 100, 50, units="mm", background_ratio=0.9)
            plate.load_texture("flat", png=flat_png(0.8))
            plate.place_sprite("pad", "flat", 10, 10, 30, 20)  # 10..40 × 10..30 mm
            plate.place_sprite("plain", "flat", 60, 10, 30, 20)  # 60..90: the same friction, no effect
            reply = plate.attach_effects("pad", file=ahap, release_s=0.01)
            assert reply["effects"] == 1 and reply["regions"] == 1
            plate.wait_rendered()
            slide(plate, [(25, 20), (75, 20), (25, 25)])  # onto pad, over to plain, back onto pad
            hold(plate, 50, 40, seconds=0.3)  # the background
            # a sprite over part of pad: where it covers pad, pad's effect does not play
            plate.place_sprite("cover", "flat", 30, 10, 20, 30, z=1)
            plate.wait_rendered()
            hold(plate, 35, 15, seconds=0.3)  # on pad under cover
            plate.detach_effects("pad")
            plate.wait_rendered()
            hold(plate, 20, 15, seconds=0.3)  # on pad, nothing attached any more
    envelope = read_envelope(envelope_csv)
    flat = png_ratio(0.8)
    for x, y in ((25, 20), (25, 25)):
        depth, frequency = modulation(settled(rows_at(envelope, x, y)))
        assert depth == pytest.approx(0.4, abs=0.02)  # (1 - cos)/2 swings the full depth
        assert frequency == pytest.approx(50.0, abs=3.0)
        assert settled(rows_at(envelope, x, y))["target_ratio"].max() == pytest.approx(flat, abs=0.01)
    for (x, y), ratio in (((75, 20), flat), ((50, 40), 0.9), ((35, 15), flat), ((20, 15), flat)):
        rows = settled(rows_at(envelope, x, y))
        assert len(rows) > 100, f"nothing rendered at ({x}, {y}) mm"
        assert np.ptp(rows["target_ratio"]) < 0.01 and np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)


def test_an_effect_object_follows_its_sprite_and_bad_attachments_are_refused(tmp_path):
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            plate.set_view("main", 400, 200, units="px", width_mm=100, height_mm=50)
            plate.load_texture("flat", png=flat_png(0.7))
            plate.place_sprite("knob", "flat", 40, 40, 80, 80)  # 10..30 × 10..30 mm
            # a steady drop of 0.5 while on it: the friction 0.5 lower there
            reply = plate.attach_effects("knob", effect=effects.Constant(0.5))
            assert reply["regions"] == 1
            with pytest.raises(Unknown, match="no sprite 'nobody'"):
                plate.attach_effects("nobody", effect=effects.Constant(0.5))
            with pytest.raises(BadMessage, match="give one of"):
                plate.attach_effects("knob")
            with pytest.raises(EngineRefused, match="frequency_hz"):
                plate.attach_effects("knob", effect={"type": "sine", "frequency_hz": -3, "depth": 0.2})
            with pytest.raises(EngineRefused):
                plate.attach_effects("knob", file=tmp_path / "missing.ahap")
            with pytest.raises(Unknown, match="no effects attached"):
                plate.detach_effects("nobody")
            plate.wait_rendered()
            hold(plate, 80, 80, seconds=0.3)  # (20, 20) mm: on it
            plate.move_sprite("knob", 240, 40)  # now 60..80 × 10..30 mm: the effect goes with it
            plate.wait_rendered()
            hold(plate, 84, 84, seconds=0.3)  # (21, 21) mm: where it was
            hold(plate, 280, 80, seconds=0.3)  # (70, 20) mm: where it is
            plate.remove_sprite("knob")  # its effects go with it
            with pytest.raises(Unknown, match="no effects attached"):
                plate.detach_effects("knob")
    envelope = read_envelope(envelope_csv)
    flat = png_ratio(0.7)
    for (x, y), ratio in (((20, 20), flat - 0.5), ((21, 21), 1.0), ((70, 20), flat - 0.5)):
        rows = settled(rows_at(envelope, x, y))
        assert len(rows) > 100, f"nothing rendered at ({x}, {y}) mm"
        assert np.median(rows["target_ratio"]) == pytest.approx(ratio, abs=0.01)
