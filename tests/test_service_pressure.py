"""A client's pointer pressure becomes the finger's force: × 1 N by default, × the rig's ``[touch]
pressure_full_scale_n`` with ``serve --rig``, at least 0.05 N; a mouse's pressure is ignored and ``force_n`` wins.
Checked on the force the engine was given, as ``touch.seen`` reports it, on a real ``serve`` process."""

import pytest
from conftest import ROOT
from service_run import flat_png, running_service

from ultraglide.client import Client


def forces_seen(plate, touches: list[dict]) -> list[float | None]:
    """Each touch pressed at (25, 25) mm and held until ``touch.seen`` reports it, then lifted; the forces seen."""
    plate.set_view("main", 100, 50, units="mm")
    plate.load_texture("flat", png=flat_png(0.5))
    plate.place_sprite("all", "flat", 0, 0, 100, 50)
    plate.wait_rendered()
    plate.subscribe(touch=True)
    forces = []
    for options in touches:
        plate.touch(25, 25, "down", **options)
        down = next(m for m in plate.events(10.0) if m["type"] == "touch.seen" and m["down"])
        forces.append(down["force_n"])
        plate.touch(25, 25, "up")
        next(m for m in plate.events(10.0) if m["type"] == "touch.seen" and not m["down"])
    return forces


def rig_with_pressure_scale(tmp_path, full_scale_n: float):
    text = (ROOT / "examples" / "rig.toml").read_text()
    rig = tmp_path / "rig.toml"
    rig.write_text(text[:text.index("[touch]")] + f"[touch]\npressure_full_scale_n = {full_scale_n}\n"
                   + text[text.index("[display]"):])
    return rig


@pytest.mark.parametrize("full_scale_n", [None, 4.0])
def test_a_client_s_pressure_is_scaled_by_the_rig(tmp_path, full_scale_n):
    options = ["--device", "sim"] if full_scale_n is None else \
        ["--rig", rig_with_pressure_scale(tmp_path, full_scale_n), "--device", "sim"]
    scale = 1.0 if full_scale_n is None else full_scale_n
    with running_service("--port", "0", *options) as (process, address):
        with Client(address["url"]) as plate:
            forces = forces_seen(plate, [{"pressure": 0.5}, {"pressure": 0.001}, {"pressure": 0.5, "force_n": 3.0},
                                         {"pressure": 0.5, "pointer_type": "mouse"},
                                         {"pressure": 0.25, "pointer_type": "pen"}])
    assert forces[0] == pytest.approx(0.5 * scale)
    assert forces[1] == pytest.approx(0.05)  # a pressed pointer gives at least 0.05 N
    assert forces[2] == pytest.approx(3.0)  # a force given wins over the pressure
    assert forces[4] == pytest.approx(0.25 * scale)
    assert forces[3] is None  # a mouse's pressure is not a force: none given, the engine's default
