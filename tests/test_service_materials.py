"""Textures from a glTF scene's haptic material, loaded through the client from a scene ``ultraglide texture
export-gltf`` wrote, placed as a sprite: the engine's envelope record under the finger is the texture's friction
read from the texture file itself."""

import numpy as np
import pytest
from service_run import hold, read_envelope, rows_at, running_service
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.texture import Texture

from ultraglide.client import BadMessage, Client, TextureRefused


def two_halves(path):
    """A 40 × 20 mm texture: 0.3 on its left half, 0.8 on its right; as the file holds it."""
    values = np.full((40, 80), 0.3, dtype=np.float32)
    values[:, 40:] = 0.8
    save_texture(Texture(values, 40.0, 20.0, name="halves"), path)
    return load_texture(path)


def test_a_material_of_an_exported_scene_is_felt_where_its_sprite_lies(tmp_path, cli):
    texture = two_halves(tmp_path / "halves.png")
    scene = tmp_path / "halves.glb"
    cli("texture", "export-gltf", tmp_path / "halves.png", "-o", scene, check=True)
    envelope_csv = tmp_path / "envelope.csv"
    with running_service("--port", "0", "--envelope-csv", envelope_csv) as (process, address):
        with Client(address["url"]) as plate:
            plate.set_view("main", 100, 50, units="mm", background_ratio=0.95)
            # by index, then by the name the scene gives it: the size is the scene's own (its UV mapping)
            loaded = plate.load_material("g", scene, 0)
            assert (loaded["width_mm"], loaded["height_mm"]) == pytest.approx((40.0, 20.0), abs=1e-3)
            assert (loaded["cols"], loaded["rows"]) == (texture.cols, texture.rows)
            named = plate.load_material("h", scene, loaded["name"], width_mm=20)  # half the size, same shape
            assert (named["width_mm"], named["height_mm"]) == pytest.approx((20.0, 10.0), abs=1e-3)
            with pytest.raises(TextureRefused, match="no haptic material 'nothing'"):
                plate.load_material("x", scene, "nothing")
            with pytest.raises(BadMessage, match="a .gltf or .glb file"):
                plate.load_texture("x", library="grating-1mm", material=0)
            with pytest.raises(BadMessage, match="leave out height_mm"):
                plate.load_texture("x", file=scene, height_mm=10)
            plate.place_sprite("s", "g", 10, 10, 40, 20)  # 10..50 × 10..30 mm, at its own size
            plate.wait_rendered()
            hold(plate, 20, 20)  # 10 mm into it: its left half
            hold(plate, 40, 20)  # 30 mm into it: its right half
            hold(plate, 70, 40)  # off it: the background
    envelope = read_envelope(envelope_csv)
    for (x, y), (u, v) in (((20, 20), (10, 10)), ((40, 20), (30, 10))):
        expected = float(texture.values[round(v / 20 * texture.rows), round(u / 40 * texture.cols)])
        rows = rows_at(envelope, x, y)
        assert len(rows) > 100, f"nothing rendered at ({x}, {y}) mm"
        assert np.median(rows["target_ratio"]) == pytest.approx(expected, abs=0.01)
    assert np.median(rows_at(envelope, 70, 40)["target_ratio"]) == pytest.approx(0.95, abs=0.01)
