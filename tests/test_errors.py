"""One root for every error of ours: ``except ultraglide.UltraglideError`` catches each refusal of the library,
raised here for real by the library itself, and each error keeps its older base."""

from __future__ import annotations

import numpy as np
import pytest

import ultraglide


def _texture_error(tmp_path):
    not_a_texture = tmp_path / "notes.txt"
    not_a_texture.write_text("hello")
    ultraglide.load_texture(not_a_texture)


def _model_error(tmp_path):
    ultraglide.load_model("no-such-model")


def _render_error(tmp_path):
    ultraglide.RenderSettings(audio_rate_hz=100000, control_rate_hz=12000.0)  # not a whole multiple


def _device_error(tmp_path):
    from ultraglide.devices.serial.link import open_port

    open_port(str(tmp_path / "no-such-port"), 921600)


def _carrier_error(tmp_path):
    ultraglide.load_profile("sim-plate").check_carrier(30000.0)  # Hz, outside the plate's 20-28 kHz


def _profile_error(tmp_path):
    ultraglide.load_profile("no-such-plate")


def _engine_error(tmp_path):
    ultraglide.EngineConfig()  # a config alone is fine; a texture that does not exist is refused at start
    with ultraglide.Engine.start(ultraglide.EngineConfig(texture=str(tmp_path / "missing.png"), device="null",
                                                         realtime_priority=False)):
        pass


def _fit_error(tmp_path):
    from ultraglide.devices.characterisation.resonance import fit_resonance

    fit_resonance(np.array([25000.0, 25001.0]), np.array([0.0, 0.0]))


def _protocol_error(tmp_path):
    from ultraglide.devices import protocol

    protocol.parse_setpoint_codes(b"\x01\x02")  # a payload far too short


def _usage_error(tmp_path):
    from ultraglide.apps.cli.parser import build_parser

    args = build_parser().parse_args(["plate", "sweep", "--from-hz", "26000", "--to-hz", "25000",
                                      "-o", str(tmp_path / "p.toml")])
    args.run(args)  # refused before any device opens: the range is upside down


REFUSALS = {
    "TextureError": (_texture_error, ValueError),
    "ModelError": (_model_error, ValueError),
    "RenderError": (_render_error, ValueError),
    "DeviceError": (_device_error, RuntimeError),
    "CarrierError": (_carrier_error, RuntimeError),
    "ProfileError": (_profile_error, RuntimeError),
    "FitError": (_fit_error, ValueError),
    "ProtocolError": (_protocol_error, ValueError),
    "UsageError": (_usage_error, ValueError),
}


@pytest.mark.parametrize("name", sorted(REFUSALS))
def test_every_refusal_is_caught_by_the_root_and_keeps_its_old_base(name, tmp_path):
    provoke, old_base = REFUSALS[name]
    with pytest.raises(ultraglide.UltraglideError) as caught:
        provoke(tmp_path)
    assert type(caught.value).__name__ == name
    assert isinstance(caught.value, old_base)
    assert str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.slow
def test_an_engine_that_cannot_start_is_caught_by_the_root(tmp_path):
    with pytest.raises(ultraglide.UltraglideError) as caught:
        _engine_error(tmp_path)
    assert type(caught.value).__name__ == "EngineError" and isinstance(caught.value, ValueError)
    assert "missing.png" in str(caught.value)


def test_every_error_class_of_ours_derives_from_the_root():
    import importlib
    import pkgutil

    found = set()
    for package in ("textures", "devices", "render", "apps"):
        root = importlib.import_module(f"ultraglide.{package}")
        for info in pkgutil.walk_packages(root.__path__, f"ultraglide.{package}."):
            if info.name.startswith("ultraglide.apps.demo") or info.name.endswith("__main__"):
                continue  # pygame's window code: imported by its own tests
            module = importlib.import_module(info.name)
            for value in vars(module).values():
                if (isinstance(value, type) and issubclass(value, Exception) and value.__module__ == info.name):
                    found.add(value)
    assert len(found) >= 8, found
    strays = {cls.__qualname__ for cls in found if not issubclass(cls, ultraglide.UltraglideError)}
    assert not strays, f"errors of ours outside the root: {strays}"
