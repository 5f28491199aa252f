"""glTF scenes with MPEG_haptic_material: friction maps in (texture import, and wherever a texture is taken) and
out (texture export-gltf), checked by the Khronos glTF-Validator and by scenes built here by hand."""

import base64
import io
import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from PIL import Image

VALIDATOR = ROOT / ".venv" / "node_modules" / "gltf-validator" / "package.json"


def validate(path: Path) -> dict:
    """The Khronos glTF-Validator's report on a file (npm gltf-validator, installed by ./run tests)."""
    if shutil.which("node") is None or not VALIDATOR.exists():
        pytest.fail("the glTF-Validator is not installed: run ./run tests (it installs Node and the validator)")
    result = subprocess.run(["node", str(ROOT / "tests" / "gltf_validator.js"), str(path)], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def png_bytes(array: np.ndarray, mode: str | None = None) -> bytes:
    stream = io.BytesIO()
    Image.fromarray(array, mode).save(stream, format="PNG")
    return stream.getvalue()


def scene(images: list[dict], quad_m=(0.1, 0.05), uv_max=(1.0, 1.0), scale=(1.0, 1.0, 1.0), materials=None,
          buffers_uri: str | None = None, positions=None) -> tuple[dict, bytes]:
    """A glTF document built by hand (not by ultraglide's writer): one quad of ``quad_m`` metres whose texture
    coordinates run 0..``uv_max``, on a node scaled by ``scale``, wearing haptic material 0."""
    w, h = quad_m
    pos = np.array(positions if positions is not None else [[0, h, 0], [w, h, 0], [0, 0, 0], [w, 0, 0]], np.float32)
    uv = np.array([[0, 0], [uv_max[0], 0], [0, uv_max[1]], [uv_max[0], uv_max[1]]], np.float32)
    blob = pos.tobytes() + uv.tobytes()
    document = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "scale": list(scale)}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}],
                    "extensions": {"MPEG_haptic_material": {"hapticMaterialIndex": 0}}}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48,
                                                                           "byteLength": 32}],
        "buffers": [{"byteLength": len(blob)}],
        "images": images,
        "textures": [{"source": k} for k in range(len(images))],
        "extensionsUsed": ["MPEG_haptic_material"],
        "extensions": {"MPEG_haptic_material": {"materials": materials or [
            {"name": "rough", "friction": [{"texture": {"index": 0}, "type": "High_Resolution"}]}]}},
    }
    if buffers_uri is not None:
        document["buffers"][0]["uri"] = buffers_uri
    return document, blob


def glb(document: dict, blob: bytes, extra_images: list[bytes] = ()) -> bytes:
    """A GLB of ``document`` with ``blob`` and images appended to its BIN chunk (as bufferViews)."""
    blob = bytearray(blob)
    for data in extra_images:
        blob.extend(b"\0" * (-len(blob) % 4))
        document["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        blob.extend(data)
    blob.extend(b"\0" * (-len(blob) % 4))
    document["buffers"][0]["byteLength"] = len(blob)
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


def data_uri(data: bytes, mime: str = "application/octet-stream") -> str:
    return f"data:{mime};base64," + base64.b64encode(data).decode()


@pytest.fixture
def texture(tmp_path):
    path = tmp_path / "g.png"
    run_cli("texture", "new", "noise", "--size-mm", "40x25", "--cutoff-mm", "1", "-o", path, check=True)
    return path


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_export_passes_the_validator_and_reads_back_within_one_code(texture, tmp_path, suffix):
    from ultraglide.textures.fileformat import load_texture

    out = tmp_path / f"scene{suffix}"
    run_cli("texture", "export-gltf", texture, "-o", out, check=True)
    report = validate(out)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    info = report["info"]
    assert info["totalVertexCount"] == 4 and info["drawCallCount"] == 1
    assert "MPEG_haptic_material" in info["extensionsUsed"]
    back = tmp_path / "back.png"
    run_cli("texture", "import", out, "-o", back, check=True)
    original, read = load_texture(texture), load_texture(back)
    codes = np.abs(np.round(original.values * 65535).astype(int) - np.round(read.values * 65535).astype(int))
    assert codes.max() <= 1
    assert (read.width_mm, read.height_mm) == pytest.approx((40.0, 25.0), rel=1e-6)  # from the quad's UV extent
    assert read.outside == original.outside and read.name == original.name


def test_the_exported_quad_is_the_texture_s_physical_size_in_metres(texture, tmp_path):
    out = tmp_path / "scene.glb"
    run_cli("texture", "export-gltf", texture, "-o", out, check=True)
    data = out.read_bytes()
    json_length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + json_length])
    position = document["accessors"][document["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    assert position["max"][:2] == pytest.approx([0.040, 0.025])
    haptic = document["extensions"]["MPEG_haptic_material"]["materials"][0]
    image = document["images"][document["textures"][haptic["friction"][0]["texture"]["index"]]["source"]]
    view = document["bufferViews"][image["bufferView"]]
    start = 20 + json_length + 8 + view.get("byteOffset", 0)
    with Image.open(io.BytesIO(data[start:start + view["byteLength"]])) as friction:  # Pillow reads it alone
        assert friction.mode.startswith("I;16") and friction.size == (400, 250)


def test_a_hand_built_glb_gives_its_size_from_the_uv_mapping_and_lists_its_materials(tmp_path):
    from ultraglide.textures.fileformat import load_texture

    gray = np.tile(np.linspace(0, 255, 64, dtype=np.uint8), (32, 1))
    materials = [{"name": "rough", "friction": [{"texture": {"index": 0}, "type": "High_Resolution"}],
                  "temperature": [{"texture": {"index": 0}, "type": "Other"}]},
                 {"name": "soft", "stiffness": [{"texture": {"index": 0}, "type": "Low_Resolution"}]}]
    document, blob = scene([{"bufferView": 2, "mimeType": "image/png"}], quad_m=(0.1, 0.05), uv_max=(2.0, 1.0),
                           scale=(1.0, 2.0, 1.0), materials=materials)
    path = tmp_path / "hand.glb"
    path.write_bytes(glb(document, blob, [png_bytes(gray)]))
    facts = json.loads(run_cli("texture", "info", path, "--json", check=True).stdout)
    listed = facts["haptic_materials"]
    assert [m["name"] for m in listed] == ["rough", "soft"]
    # u runs 0..2 over 100 mm: one texture is 50 mm wide; v 0..1 over 50 mm scaled twice by the node: 100 mm
    assert listed[0]["size_mm"] == [50.0, 100.0]
    assert listed[1]["friction_textures"] == [] and listed[1]["properties"] == ["stiffness"]
    out = tmp_path / "t.png"
    result = run_cli("texture", "import", path, "--material", "rough", "-o", out, check=True)
    assert "temperature" in result.stderr  # what a friction display does not render is said
    read = load_texture(out)
    assert (read.width_mm, read.height_mm) == pytest.approx((50.0, 100.0))
    assert read.values[0, 0] == 0.0 and read.values[0, -1] == 1.0  # the texel is the ratio by default
    mapped = tmp_path / "m.png"
    run_cli("texture", "import", path, "--material", "0", "--texel-range", "0.4", "0.9", "--invert", "-o", mapped,
            check=True)
    values = load_texture(mapped).values
    assert values[0, 0] == pytest.approx(0.9, abs=1 / 65535) and values[0, -1] == pytest.approx(0.4, abs=1 / 65535)
    refused = run_cli("texture", "import", path, "--material", "soft", "-o", tmp_path / "s.png")
    assert "no friction texture" in assert_one_line_error(refused)
    assert not (tmp_path / "s.png").exists()


def test_a_gltf_with_an_external_colour_image_and_a_data_uri_buffer(tmp_path):
    from ultraglide.textures.fileformat import load_texture

    red = np.zeros((16, 16, 3), np.uint8)
    red[:, :, 0] = 200  # the first channel carries the map
    red[:, :, 1] = 17
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "friction map.png").write_bytes(png_bytes(red, "RGB"))
    document, blob = scene([{"uri": "maps/friction%20map.png"}], quad_m=(0.03, 0.03))
    document["buffers"][0]["uri"] = data_uri(blob)
    path = tmp_path / "scene.gltf"
    path.write_text(json.dumps(document))
    out = tmp_path / "t.png"
    run_cli("texture", "import", path, "-o", out, check=True)
    read = load_texture(out)
    assert read.values.max() == pytest.approx(200 / 255) and (read.width_mm, read.height_mm) == pytest.approx((30, 30))


def test_width_is_asked_for_when_the_scene_does_not_say_it(tmp_path):
    from ultraglide.textures.fileformat import load_texture

    document, blob = scene([{"uri": data_uri(png_bytes(np.full((10, 20), 128, np.uint8)), "image/png")}])
    document["meshes"][0].pop("extensions")  # no mesh wears the material
    path = tmp_path / "scene.gltf"
    document["buffers"][0]["uri"] = data_uri(blob)
    path.write_text(json.dumps(document))
    refused = run_cli("texture", "import", path, "-o", tmp_path / "t.png")
    assert "--width-mm" in assert_one_line_error(refused)
    run_cli("texture", "import", path, "--width-mm", "60", "-o", tmp_path / "t.png", check=True)
    read = load_texture(tmp_path / "t.png")
    assert (read.width_mm, read.height_mm) == pytest.approx((60.0, 30.0))  # the image's aspect


def test_a_scene_works_wherever_a_texture_is_taken(texture, tmp_path):
    import ultraglide

    out = tmp_path / "scene.glb"
    run_cli("texture", "export-gltf", texture, "-o", out, check=True)
    loaded = ultraglide.resolve_texture(str(out))
    assert (loaded.width_mm, loaded.height_mm) == pytest.approx((40.0, 25.0))
    summary = json.loads(run_cli("export", out, "-o", tmp_path / "s.wav", "--duration-s", "0.2", "--json",
                                 check=True).stdout)
    assert summary["duration_s"] >= 0.2 and (tmp_path / "s.wav").stat().st_size > 0


def hostile_cases(tmp_path: Path) -> dict[str, Path]:
    cases = {}
    good, blob = scene([{"bufferView": 2, "mimeType": "image/png"}])
    image = png_bytes(np.full((8, 8), 100, np.uint8))
    data = glb(json.loads(json.dumps(good)), blob, [image])
    lying = bytearray(data)
    struct.pack_into("<I", lying, 12, 1 << 30)  # the JSON chunk claims a gigabyte
    cases["lying chunk"] = lying
    short = bytearray(data)
    struct.pack_into("<I", short, 8, len(data) + 1000)  # the header's total is not the file's
    cases["lying total"] = short
    cases["deep nesting"] = b'{"asset": {"version": "2.0"}, "extras": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    nan, _ = scene([{"bufferView": 2, "mimeType": "image/png"}], positions=[[float("nan"), 0, 0]] * 4)
    cases["NaN positions"] = glb(nan, np.array([[np.nan, 0, 0]] * 4, np.float32).tobytes() + blob[48:], [image])
    huge = json.loads(json.dumps(good))
    huge["accessors"][0]["count"] = 4_000_000_000
    cases["huge count"] = glb(huge, blob, [image])
    many = json.loads(json.dumps(good))
    many["nodes"] = [{}] * 200_000
    cases["huge array"] = glb(many, blob, [image])
    outside, _ = scene([{"uri": "../secret.png"}])
    outside["buffers"][0]["uri"] = data_uri(blob)
    cases["outside the folder"] = json.dumps(outside).encode()
    device, _ = scene([{"uri": "/dev/zero"}])
    device["buffers"][0]["uri"] = data_uri(blob)
    cases["a device"] = json.dumps(device).encode()
    linked, _ = scene([{"uri": "zero.png"}])
    linked["buffers"][0]["uri"] = data_uri(blob)
    cases["a link to a device"] = json.dumps(linked).encode()
    fifo, _ = scene([{"uri": "pipe.png"}])
    fifo["buffers"][0]["uri"] = data_uri(blob)
    cases["a FIFO"] = json.dumps(fifo).encode()
    web, _ = scene([{"uri": "https://example.com/map.png"}])
    web["buffers"][0]["uri"] = data_uri(blob)
    cases["a URL"] = json.dumps(web).encode()
    paths = {}
    folder = tmp_path / "scenes"
    folder.mkdir()
    (tmp_path / "secret.png").write_bytes(image)
    os.symlink("/dev/zero", folder / "zero.png")
    os.mkfifo(folder / "pipe.png")
    for name, content in cases.items():
        suffix = ".glb" if content[:4] == b"glTF" else ".gltf"
        path = folder / (name.replace(" ", "_") + suffix)
        path.write_bytes(bytes(content))
        paths[name] = path
    return paths


def test_hostile_scenes_are_refused_in_one_line(tmp_path):
    for name, path in hostile_cases(tmp_path).items():
        out = tmp_path / "t.png"
        result = run_cli("texture", "import", path, "--width-mm", "10", "-o", out, timeout=60)
        line = assert_one_line_error(result)
        assert str(path) in line, (name, line)
        assert not out.exists(), name
