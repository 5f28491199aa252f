"""glTF 2.0 scenes with ``MPEG_haptic_material`` (ISO/IEC 23090-14): friction maps in and out.

Reading (:func:`read_scene`, :func:`load_friction_texture`): a ``.gltf`` (JSON, its buffers and images as data
URIs or files beside it) or a ``.glb`` (binary: a JSON chunk and a BIN chunk). The document's
``extensions.MPEG_haptic_material.materials`` lists the haptic materials; each has arrays of textures per
property (``friction``, ``stiffness``, ``vibrotactileTexture``, ``temperature``, ``vibration``, ``custom``), each
a ``textureInfo`` with a ``type`` (``High_Resolution``, ``Low_Resolution``, ``Reference``, ``Other``). A mesh
names its haptic material with ``extensions.MPEG_haptic_material.hapticMaterialIndex``.

A material's ``friction`` texture (its ``High_Resolution`` one first, else the first listed) becomes a friction
map through :class:`~ultraglide.textures.formats.mapping.TexelMapping`. Its physical size comes from the meshes
that wear the material: the affine map from their texture coordinates to their positions (with their nodes'
transforms, glTF's metres) gives the millimetres one whole texture spans along u and v, when the mapping is
flat (every vertex within 1 % of the fit); otherwise the caller gives the width.

Every file is checked at the edge, in bounded time and memory: the GLB's header and chunk lengths against the
file's real size, the JSON's size and depth, every index and byte range against what it points into, counts
against limits, numbers for finiteness. A URI may name a file in the scene's own folder (or below it) only,
a regular file (never a device, a pipe or a folder), or be a ``data:`` URI; nothing else is read.

Writing (:func:`write_gltf`): a quad at the texture's physical size in the XY plane (metres, facing +Z), its
haptic material's ``friction`` texture the map as a 16-bit grayscale PNG (with ultraglide's metadata chunk, so
it reads back exactly) and a colour preview (at most 1024 pixels a side) as the base colour of its PBR material,
for any viewer.
"""

from __future__ import annotations

import base64
import io
import json
import math
import os
import struct
import sys
import urllib.parse
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image, PngImagePlugin, UnidentifiedImageError
from ultraglide.textures import effects as effects_format
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import (
    CHUNK,
    FULL_SCALE,
    MAX_SIDE_MM,
    MIN_SIDE_MM,
    _validated,
    held_size,
    metadata_of,
    pillow_failure,
    quantise,
)
from ultraglide.textures.formats.mapping import TexelMapping
from ultraglide.textures.limits import MAX_PIXELS
from ultraglide.textures.texture import Texture

from ultraglide.atomic import AtomicFile
from ultraglide.inputs import check_input, open_input, parse_json

EXTENSION = "MPEG_haptic_material"
PROPERTIES = ("friction", "stiffness", "vibrotactileTexture", "temperature", "vibration", "custom")
TEXTURE_TYPES = ("High_Resolution", "Low_Resolution", "Reference", "Other")
GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
MAX_FILE_BYTES = 1 << 30  # a GLB or a buffer file: a 16k × 16k 16-bit map is 512 MB before compression
MAX_JSON_BYTES = 16 << 20  # a scene's JSON: every array of a real scene fits many times over
MAX_ITEMS = 100_000  # entries of any top-level array (nodes, meshes, accessors ...)
MAX_VERTICES = 10_000_000  # elements of an accessor read for the size
PREVIEW_SIDE = 1024  # pixels along the base colour preview's longer side, at most
FLAT_TOLERANCE = 0.01  # a UV mapping is flat when every vertex lies within 1 % of the scene's extent of the fit
COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


@dataclass(frozen=True)
class HapticMaterial:
    """A haptic material of a scene, described without reading its images.

    ``index`` is its place in the document's ``MPEG_haptic_material.materials``; ``friction`` the
    (texture index, type, texCoord) of each friction texture; ``properties`` the properties it has
    textures for; ``meshes`` the meshes that wear it.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> material = read_scene(write_gltf(grating(2.0), pathlib.Path(tempfile.mkdtemp()) / "g.glb")).materials[0]
    >>> material.index, material.name, material.friction, material.meshes
    (0, 'grating-sine', ((0, 'High_Resolution', 0),), (0,))
    """

    index: int
    name: str
    friction: tuple[tuple[int, str, int], ...]
    properties: tuple[str, ...]
    meshes: tuple[int, ...]


@dataclass
class Scene:
    """A glTF document read and checked: its JSON, its BIN chunk (GLB) and the folder its URIs resolve in.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> scene = read_scene(write_gltf(grating(2.0), pathlib.Path(tempfile.mkdtemp()) / "grating.glb"))
    >>> scene.path.name, scene.document["asset"]["version"], scene.binary is not None, len(scene.materials)
    ('grating.glb', '2.0', True, 1)
    """

    path: Path
    document: dict
    binary: bytes | None
    folder: Path
    materials: tuple[HapticMaterial, ...] = ()
    _buffers: dict = field(default_factory=dict)

    def fail(self, message: str) -> TextureError:
        """A TextureError naming the scene's file and what is wrong with it (for the caller to raise).

        Parameters
        ----------
        message : str
            What is wrong, one line.

        Returns
        -------
        TextureError

        Examples
        --------
        >>> import pathlib, tempfile
        >>> from ultraglide import grating
        >>> scene = read_scene(write_gltf(grating(2.0), pathlib.Path(tempfile.mkdtemp()) / "grating.glb"))
        >>> str(scene.fail("mesh 0 has no positions"))
        '.../grating.glb: mesh 0 has no positions'
        """
        return TextureError(f"{self.path}: {message}")


def is_gltf(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a glTF scene by its extension (``.gltf`` or ``.glb``).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    bool

    Examples
    --------
    >>> is_gltf("plate.GLB"), is_gltf("scene.gltf"), is_gltf("map.png")
    (True, True, False)
    """
    return Path(path).suffix.lower() in (".gltf", ".glb")


# ---- reading --------------------------------------------------------------------------------------------------
def read_scene(path: str | os.PathLike) -> Scene:
    """A glTF scene's document, checked, and its haptic materials.

    Parameters
    ----------
    path : str or path-like
        A ``.glb`` or ``.gltf`` file (a regular file; pipes and devices are refused unread).

    Returns
    -------
    Scene
        With ``materials``: every haptic material of ``MPEG_haptic_material``.

    Raises
    ------
    TextureError
        One line saying what is wrong: not glTF 2.0, a GLB whose lengths lie, JSON too large or too deep,
        an index out of range, a bad haptic material.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> path = write_gltf(grating(2.0, size_mm=(40, 20)), pathlib.Path(tempfile.mkdtemp()) / "grating.glb")
    >>> [material.name for material in read_scene(path).materials]
    ['grating-sine']
    """
    path = Path(path)
    with open_input(path, "glTF file", TextureError) as stream:
        size = os.fstat(stream.fileno()).st_size
        if size > MAX_FILE_BYTES:
            raise TextureError(f"{path}: {size / (1 << 20):,.0f} MiB, more than the {MAX_FILE_BYTES >> 20} MiB "
                               "ultraglide reads from a glTF file")
        head = stream.read(4)
        stream.seek(0)
        if head == GLB_MAGIC:
            text, binary = _read_glb(stream, size, path)
        else:
            if size > MAX_JSON_BYTES:
                raise TextureError(f"{path}: a .gltf (JSON) of more than {MAX_JSON_BYTES >> 20} MiB; put its "
                                   "images and buffers in files beside it, or make it a .glb")
            text, binary = stream.read(MAX_JSON_BYTES + 1), None
    document = parse_json(text, str(path), TextureError, what="glTF file")
    scene = Scene(path, document if isinstance(document, dict) else {}, binary, path.resolve().parent)
    if not isinstance(document, dict):
        raise scene.fail("not a glTF document (its JSON must be an object)")
    _check_document(scene)
    scene.materials = _haptic_materials(scene)
    return scene


def _read_glb(stream, size: int, path: Path) -> tuple[bytes, bytes | None]:
    """The JSON and BIN chunks of a GLB, every length checked against the file's real size before reading."""
    header = stream.read(12)
    if len(header) < 12:
        raise TextureError(f"{path}: a GLB header is 12 bytes, the file has {len(header)}")
    _, version, length = struct.unpack("<4sII", header)
    if version != 2:
        raise TextureError(f"{path}: GLB version {version}; ultraglide reads glTF 2.0")
    if length != size:
        raise TextureError(f"{path}: its GLB header says {length:,} bytes, the file has {size:,} (truncated or "
                           "damaged)")
    chunks: list[tuple[int, bytes]] = []
    offset = 12
    while offset < size:
        if size - offset < 8:
            raise TextureError(f"{path}: a chunk header at byte {offset} is cut short")
        chunk_length, kind = struct.unpack("<II", stream.read(8))
        offset += 8
        if chunk_length > size - offset:
            raise TextureError(f"{path}: a chunk at byte {offset - 8} claims {chunk_length:,} bytes, only "
                               f"{size - offset:,} follow (the file's lengths lie)")
        if not chunks and kind != CHUNK_JSON:
            raise TextureError(f"{path}: a GLB's first chunk must be its JSON")
        if kind == CHUNK_JSON and chunks:
            raise TextureError(f"{path}: a GLB has one JSON chunk, this one has more")
        if kind == CHUNK_JSON and chunk_length > MAX_JSON_BYTES:
            raise TextureError(f"{path}: a JSON chunk of {chunk_length:,} bytes, more than the "
                               f"{MAX_JSON_BYTES >> 20} MiB a scene's JSON may have")
        if kind == CHUNK_BIN and len(chunks) != 1:
            raise TextureError(f"{path}: a GLB's BIN chunk must come second, and once")
        if kind in (CHUNK_JSON, CHUNK_BIN):
            data = stream.read(chunk_length)
            if len(data) != chunk_length:
                raise TextureError(f"{path}: the file ended inside a chunk")
            chunks.append((kind, data))
        else:
            stream.seek(chunk_length, 1)  # an unknown chunk type: glTF says skip it
        offset += chunk_length
    if not chunks:
        raise TextureError(f"{path}: a GLB without its JSON chunk")
    return chunks[0][1], (chunks[1][1] if len(chunks) > 1 else None)


def _check_document(scene: Scene) -> None:
    document = scene.document
    asset = document.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if not isinstance(version, str) or not version.startswith("2."):
        raise scene.fail(f"glTF asset version {version!r}; ultraglide reads glTF 2.0")
    for key in ("nodes", "meshes", "accessors", "bufferViews", "buffers", "images", "textures", "materials",
                "scenes", "samplers"):
        items = document.get(key, [])
        if not isinstance(items, list) or not all(isinstance(item, dict) for item in items):
            raise scene.fail(f"'{key}' must be a list of objects")
        if len(items) > MAX_ITEMS:
            raise scene.fail(f"{len(items):,} {key}, more than the {MAX_ITEMS:,} ultraglide reads")


def _index(scene: Scene, value, key: str, where: str) -> int:
    """``value`` as an index into the document's ``key`` list, or one line saying it is not one."""
    items = scene.document.get(key, [])
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < len(items):
        raise scene.fail(f"{where}: {value!r} is not an index into its {len(items)} {key}")
    return value


def _int(scene: Scene, value, where: str, low: int = 0, high: int = MAX_FILE_BYTES) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise scene.fail(f"{where} must be a whole number from {low} to {high:,}, got {value!r}")
    return value


def _haptic_materials(scene: Scene) -> tuple[HapticMaterial, ...]:
    extension = (scene.document.get("extensions") or {})
    if not isinstance(extension, dict):
        raise scene.fail("'extensions' must be an object")
    haptic = extension.get(EXTENSION)
    if haptic is None:
        return ()
    materials = haptic.get("materials") if isinstance(haptic, dict) else None
    if not isinstance(materials, list) or not materials or len(materials) > MAX_ITEMS:
        raise scene.fail(f"{EXTENSION}: 'materials' must be a list of 1 to {MAX_ITEMS:,} haptic materials")
    wearers: dict[int, list[int]] = {}
    for number, mesh in enumerate(scene.document.get("meshes", [])):
        own = (mesh.get("extensions") or {}).get(EXTENSION) if isinstance(mesh.get("extensions"), dict) else None
        if own is not None:
            where = f"mesh {number}'s {EXTENSION}"
            if not isinstance(own, dict) or "hapticMaterialIndex" not in own:
                raise scene.fail(f"{where} needs a hapticMaterialIndex")
            index = own["hapticMaterialIndex"]
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(materials):
                raise scene.fail(f"{where}: hapticMaterialIndex {index!r} is not one of its {len(materials)} "
                                 "haptic materials")
            wearers.setdefault(index, []).append(number)
    out = []
    for index, material in enumerate(materials):
        where = f"haptic material {index}"
        if not isinstance(material, dict):
            raise scene.fail(f"{where} must be an object")
        name = material.get("name", "")
        if not isinstance(name, str) or len(name) > 1000:
            raise scene.fail(f"{where}: its name must be text")
        present, friction = [], []
        for prop in PROPERTIES:
            entries = material.get(prop)
            if entries is None:
                continue
            if not isinstance(entries, list) or len(entries) > MAX_ITEMS:
                raise scene.fail(f"{where}: '{prop}' must be a list of textures")
            if entries:
                present.append(prop)
            for k, entry in enumerate(entries):
                at = f"{where}'s {prop} texture {k}"
                info = entry.get("texture") if isinstance(entry, dict) else None
                if not isinstance(info, dict) or "index" not in info:
                    raise scene.fail(f"{at} needs a 'texture' with an 'index'")
                texture = _index(scene, info["index"], "textures", at)
                kind = entry.get("type", "High_Resolution")
                if kind not in TEXTURE_TYPES:
                    raise scene.fail(f"{at}: type {kind!r} is not one of {', '.join(TEXTURE_TYPES)}")
                coord = _int(scene, info.get("texCoord", 0), f"{at}'s texCoord", 0, 64)
                if prop == "friction":
                    friction.append((texture, kind, coord))
        friction.sort(key=lambda item: item[1] != "High_Resolution")  # the high-resolution one first, stably
        out.append(HapticMaterial(index, name, tuple(friction), tuple(present), tuple(wearers.get(index, ()))))
    return tuple(out)


def choose_material(scene: Scene, material: str | int | None) -> HapticMaterial:
    """The haptic material ``material`` names (its name, or its index), or the first with a friction texture.

    Parameters
    ----------
    scene : Scene
        A scene from :func:`read_scene`.
    material : str or int or None
        A material's name or index; None: the first with a friction texture.

    Returns
    -------
    HapticMaterial

    Raises
    ------
    TextureError
        No haptic material, or none by that name or index: one line listing those there are.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> scene = read_scene(write_gltf(grating(2.0), pathlib.Path(tempfile.mkdtemp()) / "grating.glb"))
    >>> choose_material(scene, None).name, choose_material(scene, 0).friction
    ('grating-sine', ((0, 'High_Resolution', 0),))
    >>> choose_material(scene, "wood")
    Traceback (most recent call last):
    ...
    ultraglide.textures.errors.TextureError: .../grating.glb: no haptic material 'wood'; it has 0 'grating-sine'
    """
    if not scene.materials:
        raise scene.fail(f"no haptic materials (no {EXTENSION} extension): it holds no friction map")
    listing = ", ".join(f"{m.index} {m.name!r}" if m.name else str(m.index) for m in scene.materials)
    if material is None:
        for candidate in scene.materials:
            if candidate.friction:
                return candidate
        raise scene.fail(f"none of its haptic materials ({listing}) has a friction texture")
    text = str(material)
    named = [m for m in scene.materials if m.name == text]
    if named:
        chosen = named[0]
    elif text.isdigit() and int(text) < len(scene.materials):
        chosen = scene.materials[int(text)]
    else:
        raise scene.fail(f"no haptic material {text!r}; it has {listing}")
    if not chosen.friction:
        raise scene.fail(f"haptic material {text!r} has no friction texture (it has "
                         f"{', '.join(chosen.properties) or 'no textures'})")
    return chosen


def _uri_bytes(scene: Scene, uri, where: str, limit: int = MAX_FILE_BYTES) -> bytes:
    """The bytes a URI names: a ``data:`` URI's, or a file's in the scene's folder (or below it) only."""
    if not isinstance(uri, str) or len(uri) > MAX_JSON_BYTES:
        raise scene.fail(f"{where}: its uri must be text")
    if uri.startswith("data:"):
        head, comma, payload = uri.partition(",")
        if not comma or not head.endswith(";base64"):
            raise scene.fail(f"{where}: a data URI must be base64 (data:...;base64,...)")
        try:
            return base64.b64decode(payload, validate=True)
        except ValueError:
            raise scene.fail(f"{where}: its data URI is not valid base64") from None
    parsed = urllib.parse.urlsplit(uri)
    if parsed.scheme or parsed.netloc:
        raise scene.fail(f"{where}: {uri[:80]!r} is not a file beside the scene; ultraglide reads files in the "
                         "scene's folder and data URIs only")
    relative = urllib.parse.unquote(parsed.path)
    if "\0" in relative or relative.startswith(("/", "\\")) or not relative:
        raise scene.fail(f"{where}: {uri[:80]!r} is not a relative path inside the scene's folder")
    target = (scene.folder / relative).resolve()
    if not target.is_relative_to(scene.folder):
        raise scene.fail(f"{where}: {uri[:80]!r} points outside the scene's folder; ultraglide reads nothing "
                         "there unless named (copy it beside the scene)")
    what = "image file" if where.startswith("image") else "buffer file"
    try:
        info = check_input(target, what, TextureError)
        if info.st_size > limit:
            raise TextureError(f"{relative} is {info.st_size:,} bytes, more than the {limit:,} expected")
        with open_input(target, what, TextureError) as stream:
            return stream.read(limit + 1)[:limit]
    except TextureError as error:
        raise scene.fail(f"{where}: {error}") from None


def _buffer(scene: Scene, index: int) -> bytes:
    if index in scene._buffers:
        return scene._buffers[index]
    buffer = scene.document["buffers"][index]
    where = f"buffer {index}"
    length = _int(scene, buffer.get("byteLength"), f"{where}'s byteLength", 1)
    if "uri" in buffer:
        data = _uri_bytes(scene, buffer["uri"], where, limit=length)
    elif index == 0 and scene.binary is not None:
        data = scene.binary
    else:
        raise scene.fail(f"{where} has no uri and no GLB BIN chunk holds it")
    if len(data) < length:
        raise scene.fail(f"{where}: byteLength {length:,}, but only {len(data):,} bytes are there")
    scene._buffers[index] = data
    return data


def _view(scene: Scene, index: int, where: str) -> tuple[memoryview, int | None]:
    """A bufferView's bytes (bounds checked) and its byteStride."""
    view = scene.document["bufferViews"][index]
    at = f"{where}'s bufferView {index}"
    buffer = _buffer(scene, _index(scene, view.get("buffer"), "buffers", at))
    offset = _int(scene, view.get("byteOffset", 0), f"{at}'s byteOffset")
    length = _int(scene, view.get("byteLength"), f"{at}'s byteLength", 1)
    if offset + length > len(buffer):
        raise scene.fail(f"{at}: bytes {offset:,} to {offset + length:,} lie beyond its buffer's {len(buffer):,}")
    stride = view.get("byteStride")
    if stride is not None:
        stride = _int(scene, stride, f"{at}'s byteStride", 4, 252)
    return memoryview(buffer)[offset:offset + length], stride


def _accessor(scene: Scene, index: int, where: str) -> np.ndarray:
    """An accessor's elements as float64 (count × components); normalised integers scaled to 0..1 or -1..1."""
    accessor = scene.document["accessors"][index]
    at = f"{where}'s accessor {index}"
    if "sparse" in accessor or "bufferView" not in accessor:
        raise scene.fail(f"{at} is sparse or has no data; ultraglide reads plain accessors")
    dtype = COMPONENTS.get(accessor.get("componentType"))
    width = WIDTHS.get(accessor.get("type"))
    if dtype is None or width is None:
        raise scene.fail(f"{at}: componentType {accessor.get('componentType')!r} or type "
                         f"{accessor.get('type')!r} is not glTF's")
    count = _int(scene, accessor.get("count"), f"{at}'s count", 1, MAX_VERTICES)
    data, stride = _view(scene, _index(scene, accessor["bufferView"], "bufferViews", at), at)
    offset = _int(scene, accessor.get("byteOffset", 0), f"{at}'s byteOffset")
    item = np.dtype(dtype).itemsize * width
    stride = stride or item
    end = offset + stride * (count - 1) + item
    if end > len(data):
        raise scene.fail(f"{at}: {count:,} elements need {end:,} bytes of a bufferView of {len(data):,}")
    if offset % np.dtype(dtype).itemsize:
        raise scene.fail(f"{at}: its byteOffset is not aligned to its components")
    raw = np.ndarray((count, width), dtype=np.dtype(dtype).newbyteorder("<"), buffer=data, offset=offset,
                     strides=(stride, np.dtype(dtype).itemsize))
    values = raw.astype(np.float64)
    if accessor.get("normalized") and dtype is not np.float32:
        values /= float(np.iinfo(dtype).max)
    if not np.all(np.isfinite(values)):
        raise scene.fail(f"{at} holds numbers that are not finite (NaN or infinity)")
    return values


def _node_matrices(scene: Scene) -> dict[int, list[np.ndarray]]:
    """Each mesh's world matrices: one per node that instances it (parents' transforms applied)."""
    nodes = scene.document.get("nodes", [])
    parent: dict[int, int] = {}
    for number, node in enumerate(nodes):
        children = node.get("children", [])
        if not isinstance(children, list):
            raise scene.fail(f"node {number}'s children must be a list")
        for child in children:
            child = _index(scene, child, "nodes", f"node {number}'s children")
            if child in parent or child == number:
                raise scene.fail(f"node {child} has two parents or is its own: the node tree is not a tree")
            parent[child] = number
    local = [_local_matrix(scene, node, number) for number, node in enumerate(nodes)]
    out: dict[int, list[np.ndarray]] = {}
    for number, node in enumerate(nodes):
        if "mesh" not in node:
            continue
        mesh = _index(scene, node["mesh"], "meshes", f"node {number}")
        matrix, at, seen = local[number], number, {number}
        while at in parent:
            at = parent[at]
            if at in seen:
                raise scene.fail(f"node {number}'s ancestors form a cycle")
            seen.add(at)
            matrix = local[at] @ matrix
        out.setdefault(mesh, []).append(matrix)
    return out


def _local_matrix(scene: Scene, node: dict, number: int) -> np.ndarray:
    def numbers(key, size, default):
        value = node.get(key, default)
        if (not isinstance(value, list) or len(value) != size
                or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                           for v in value)):
            raise scene.fail(f"node {number}'s {key} must be {size} finite numbers")
        return np.asarray(value, dtype=float)

    if "matrix" in node:
        return numbers("matrix", 16, None).reshape(4, 4).T  # column-major
    x, y, z, w = numbers("rotation", 4, [0, 0, 0, 1])
    rotation = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    matrix = np.eye(4)
    matrix[:3, :3] = rotation * numbers("scale", 3, [1, 1, 1])
    matrix[:3, 3] = numbers("translation", 3, [0, 0, 0])
    return matrix


def uv_size_mm(scene: Scene, material: HapticMaterial, tex_coord: int = 0) -> tuple[float, float] | None:
    """The millimetres one whole texture spans along u and v on the meshes that wear ``material``.

    None when no mesh maps it flatly (an affine fit of positions on texture coordinates within
    :data:`FLAT_TOLERANCE` of the extent).

    Parameters
    ----------
    scene : Scene
    material : HapticMaterial
    tex_coord : int
        The texture coordinate set (``TEXCOORD_n``).

    Returns
    -------
    tuple of (float, float) or None
        The span along u and v, mm.

    Examples
    --------
    A texture written as a 40 mm × 20 mm quad:

    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> scene = read_scene(write_gltf(grating(2.0, size_mm=(40, 20)), pathlib.Path(tempfile.mkdtemp()) / "g.glb"))
    >>> [round(side, 3) for side in uv_size_mm(scene, scene.materials[0])]
    [40.0, 20.0]
    """
    matrices = _node_matrices(scene)
    positions, coords = [], []
    for mesh_index in material.meshes:
        mesh = scene.document["meshes"][mesh_index]
        primitives = mesh.get("primitives", [])
        if not isinstance(primitives, list):
            raise scene.fail(f"mesh {mesh_index}'s primitives must be a list")
        for k, primitive in enumerate(primitives):
            attributes = primitive.get("attributes") if isinstance(primitive, dict) else None
            if not isinstance(attributes, dict):
                continue
            uv_key = f"TEXCOORD_{tex_coord}"
            if "POSITION" not in attributes or uv_key not in attributes:
                continue
            where = f"mesh {mesh_index} primitive {k}"
            position = _accessor(scene, _index(scene, attributes["POSITION"], "accessors", where), where)[:, :3]
            uv = _accessor(scene, _index(scene, attributes[uv_key], "accessors", where), where)[:, :2]
            if len(position) != len(uv) or position.shape[1] != 3 or uv.shape[1] != 2:
                raise scene.fail(f"{where}: its POSITION and {uv_key} differ in count or shape")
            for matrix in matrices.get(mesh_index, [np.eye(4)]):
                positions.append(position @ matrix[:3, :3].T + matrix[:3, 3])
                coords.append(uv)
    if not positions:
        return None
    position, uv = np.concatenate(positions), np.concatenate(coords)
    design = np.column_stack([uv, np.ones(len(uv))])
    fit, _, rank, _ = np.linalg.lstsq(design, position, rcond=None)
    if rank < 3:
        return None
    extent = float(np.max(np.ptp(position, axis=0)))
    if extent <= 0 or np.max(np.abs(design @ fit - position)) > FLAT_TOLERANCE * extent:
        return None
    width_mm, height_mm = 1000.0 * float(np.linalg.norm(fit[0])), 1000.0 * float(np.linalg.norm(fit[1]))
    if not (MIN_SIDE_MM <= width_mm <= MAX_SIDE_MM and MIN_SIDE_MM <= height_mm <= MAX_SIDE_MM):
        return None
    return width_mm, height_mm


def _image_bytes(scene: Scene, texture_index: int) -> tuple[bytes, str]:
    texture = scene.document["textures"][texture_index]
    where = f"texture {texture_index}"
    if "source" not in texture:
        raise scene.fail(f"{where} has no source image")
    image_index = _index(scene, texture["source"], "images", where)
    image = scene.document["images"][image_index]
    where = f"image {image_index}"
    if "bufferView" in image:
        data, _ = _view(scene, _index(scene, image["bufferView"], "bufferViews", where), where)
        return data, where
    if "uri" in image:
        return _uri_bytes(scene, image["uri"], where), where
    raise scene.fail(f"{where} has neither a uri nor a bufferView")


def load_friction_texture(path: str | os.PathLike, material: str | int | None = None,
                          width_mm: float | None = None, mapping: TexelMapping | None = None) -> Texture:
    """A haptic material's friction texture as an ultraglide texture.

    Parameters
    ----------
    path : str or path-like
        A ``.glb`` or ``.gltf`` scene.
    material : str or int, optional
        The haptic material: its name or index; by default the first with a friction texture.
    width_mm : float, optional
        The texture's width, mm; its height follows from the UV mapping's aspect where known, else from the
        image's. Required when the scene does not say the size (no flat UV-mapped mesh wears the material).
    mapping : TexelMapping, optional
        Texel to friction ratio (default: the ratio is the texel, white = at rest).

    Returns
    -------
    Texture
        The friction map; an image written by ultraglide keeps its metadata (kind, edges, effects).

    Raises
    ------
    TextureError
        One line: no such material, no friction texture, a size that cannot be known, a bad image.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> path = write_gltf(grating(2.0, size_mm=(40, 20)), pathlib.Path(tempfile.mkdtemp()) / "grating.glb")
    >>> texture = load_friction_texture(path, material="grating-sine", width_mm=80)
    >>> texture.width_mm, round(texture.height_mm, 6)     # the UV mapping's 2:1 kept
    (80.0, 40.0)
    """
    mapping = mapping or TexelMapping()
    scene = read_scene(path)
    chosen = choose_material(scene, material)
    texture_index, kind, tex_coord = chosen.friction[0]
    warn_unused(scene, chosen)
    data, where = _image_bytes(scene, texture_index)
    image, meta, codes = _decode(scene, data, where)
    cols, rows = image.size
    spans = uv_size_mm(scene, chosen, tex_coord)
    if width_mm is not None:
        aspect = spans[1] / spans[0] if spans else rows / cols
        size = (float(width_mm), float(width_mm) * aspect)
    elif spans is not None:
        size = spans
    else:
        raise scene.fail(f"the size of haptic material {chosen.index}'s friction map cannot be known from the "
                         "scene (no mesh wearing it maps it flatly); give its width (texture import --width-mm)")
    if not all(MIN_SIDE_MM <= side <= MAX_SIDE_MM for side in size):
        raise scene.fail(f"a friction map of {size[0]:.6g} × {size[1]:.6g} mm; each side must be "
                         f"{MIN_SIDE_MM:g} to {MAX_SIDE_MM:g} mm")
    label = chosen.name or f"material {chosen.index}"
    authoring = {"gltf_material": chosen.index, "gltf_texture_type": kind, "texel_mapping": mapping.describe()}
    fields: dict = {"name": chosen.name or Path(path).stem, "source": f"{path} ({label})",
                    "description": f"friction map of haptic material {label!r}"}
    if meta is not None:  # written by ultraglide: its own metadata holds the rest
        fields = _validated(meta, f"{where}'s ultraglide metadata")
        fields.pop("width_mm")
        fields.pop("height_mm")
        authoring = {**fields.pop("authoring"), **authoring}
        if meta.get("effects") is not None:
            fields["effects"] = effects_format.from_json(meta["effects"], where=f"{path}: {where}'s effects")
    values, authoring = _held(image, codes, size[0], size[1], authoring)
    values = mapping.ratio(values)
    return Texture(values, size[0], size[1], authoring=authoring, **fields)


def _held(image: Image.Image, codes: np.ndarray | None, width_mm: float, height_mm: float,
          authoring: dict) -> tuple[np.ndarray, dict]:
    """The decoded map's values (float32, 0..1) at the resolution a texture is held at, box-filtered as a texture
    file is (:mod:`ultraglide.textures.formats.held`: Pillow's weights, in one compiled pass). ``codes``: the
    texels when the decoder wrote them into an array of ours already (:func:`_load_into_array`)."""
    from ultraglide.textures.formats.held import held_map

    cols, rows = image.size
    size = held_size(cols, rows, width_mm, height_mm)
    if codes is None:
        if image.mode not in ("I;16", "I;16L", "I;16B", "I;16N", "L", "I"):
            image = image.convert("I")
        codes = np.asarray(image)
    if size != (cols, rows):
        authoring = {**authoring, "held_from_pixels": [cols, rows]}
    return held_map(codes, size, 255.0 if image.mode == "L" else float(FULL_SCALE)), authoring


def _load_into_array(image: Image.Image) -> np.ndarray | None:
    """Decode a gray PNG (8 or 16 bits a texel) straight into an array of ours, sparing the copy ``np.asarray``
    of a decoded image makes (a tenth of the decoding's time for a 16 M-pixel map): the image is given, before
    it loads, memory of ours that Pillow maps (``Image.frombuffer``), and its decoder writes there. None (and
    nothing loaded) for any other image, or should this Pillow not keep the memory it was given; the image then
    loads as usual."""
    if image.format != "PNG" or image.mode not in ("L", "I;16") or sys.byteorder != "little":
        return None  # Pillow keeps I;16 little-endian: the array's own order must be that
    codes = np.empty((image.height, image.width), dtype=np.uint8 if image.mode == "L" else np.uint16)
    try:
        core = Image.frombuffer(image.mode, image.size, codes, "raw", image.mode, 0, 1).im
        image.im = core
    except (AttributeError, TypeError, ValueError):
        return None
    image.load()
    return codes if image.im is core else None


class _Reader(io.RawIOBase):
    """A read-only file over bytes or a memoryview, without the copy of it ``io.BytesIO`` makes (32 MB for a
    16 M-pixel 16-bit map): Pillow reads the image through it."""

    def __init__(self, data) -> None:
        super().__init__()
        self._view = memoryview(data).cast("B")
        self._at = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        count = max(0, min(len(buffer), len(self._view) - self._at))
        buffer[:count] = self._view[self._at:self._at + count]
        self._at += count
        return count

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._at, io.SEEK_END: len(self._view)}[whence]
        self._at = max(0, base + offset)
        return self._at

    def tell(self) -> int:
        return self._at


def _decode(scene: Scene, data, where: str) -> tuple[Image.Image, dict | None, np.ndarray | None]:
    """The image's first channel (gray or red), decoded; ultraglide's metadata when it has some; and its texels
    as an array when the decoder wrote them into one (:func:`_load_into_array`), else None."""
    codes = None
    try:
        image = Image.open(_Reader(data))
        if image.width * image.height > MAX_PIXELS:
            raise scene.fail(f"{where}: {image.width}×{image.height} pixels, more than the {MAX_PIXELS:,} a texture "
                             "may have")
        codes = _load_into_array(image)
        if codes is None:
            image.load()
    except TextureError:
        raise
    except UnidentifiedImageError:
        raise scene.fail(f"{where}: not an image Pillow reads (glTF images are PNG or JPEG)") from None
    except Image.DecompressionBombError:
        raise scene.fail(f"{where}: more pixels than a texture may have ({MAX_PIXELS:,})") from None
    except MemoryError:
        raise scene.fail(f"{where}: too large to decode in the memory available") from None
    except (OSError, SyntaxError, ValueError, EOFError, struct.error) as error:
        raise scene.fail(f"{where}: {pillow_failure(error)}") from None
    meta = None
    text = image.info.get(CHUNK)
    if isinstance(text, str):
        meta = parse_json(text, f"{scene.path}: {where}'s ultraglide metadata", TextureError)
        if not isinstance(meta, dict):
            raise scene.fail(f"{where}: its ultraglide metadata must be a JSON object")
    if image.mode in ("I;16", "I;16L", "I;16B", "I;16N", "I", "L"):
        return image, meta, codes
    if image.mode in ("RGB", "RGBA", "CMYK", "YCbCr"):
        return image.getchannel(0), meta, None
    if image.mode in ("LA", "La", "P", "PA", "1"):
        return image.convert("LA").getchannel(0), meta, None
    raise scene.fail(f"{where}: image mode {image.mode} is not one ultraglide reads a friction map from")


def describe_scene(path: str | os.PathLike) -> list[dict]:
    """Each haptic material of a scene, JSON-ready.

    Parameters
    ----------
    path : str or path-like
        A ``.glb`` or ``.gltf`` file.

    Returns
    -------
    list of dict
        Per material: index, name, properties, friction textures, meshes and the size its UV mapping gives
        (mm, or None).

    Raises
    ------
    TextureError
        What :func:`read_scene` raises.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> describe_scene(write_gltf(grating(2.0, size_mm=(40, 20)), pathlib.Path(tempfile.mkdtemp()) / "g.glb"))
    [{'index': 0, 'name': 'grating-sine', 'properties': ['friction'],
      'friction_textures': [{'texture': 0, 'type': 'High_Resolution'}], 'meshes': [0], 'size_mm': [40.0, 20.0]}]
    """
    scene = read_scene(path)
    out = []
    for material in scene.materials:
        size = uv_size_mm(scene, material, material.friction[0][2]) if material.friction else None
        out.append({"index": material.index, "name": material.name, "properties": list(material.properties),
                    "friction_textures": [{"texture": t, "type": kind} for t, kind, _ in material.friction],
                    "meshes": list(material.meshes),
                    "size_mm": None if size is None else [round(size[0], 3), round(size[1], 3)]})
    return out


# ---- writing --------------------------------------------------------------------------------------------------
_PREVIEW_STOPS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)


def preview_rgb(ratio: np.ndarray) -> np.ndarray:
    """An 8-bit RGB picture of friction ratios: a perceptually ordered ramp from dark violet (0) to yellow (1).

    Parameters
    ----------
    ratio : numpy.ndarray
        Friction ratios, any shape (clipped to 0..1).

    Returns
    -------
    numpy.ndarray of uint8
        ``ratio``'s shape plus a last axis of 3 (red, green, blue).

    Examples
    --------
    >>> import numpy as np
    >>> preview_rgb(np.array([0.0, 0.5, 1.0, 2.0])).tolist()
    [[68, 1, 84], [33, 145, 140], [253, 231, 37], [253, 231, 37]]
    """
    position = np.clip(ratio, 0, 1) * (len(_PREVIEW_STOPS) - 1)
    low = np.minimum(position.astype(int), len(_PREVIEW_STOPS) - 2)
    part = (position - low)[..., None]
    colour = _PREVIEW_STOPS[low] * (1 - part) + _PREVIEW_STOPS[low + 1] * part
    return np.round(colour).astype(np.uint8)


def _png(image: Image.Image, info: PngImagePlugin.PngInfo | None = None) -> bytes:
    stream = io.BytesIO()
    image.save(stream, format="PNG", pnginfo=info, compress_level=6)
    return stream.getvalue()


def gltf_document(texture: Texture, mapping: TexelMapping | None = None) -> tuple[dict, bytes]:
    """The glTF document and its binary buffer for ``texture`` as a quad at its physical size.

    The friction texture is the map as 16-bit PNG (through ``mapping``'s inverse; with ultraglide's metadata
    chunk); the base colour a preview.

    Parameters
    ----------
    texture : Texture
    mapping : TexelMapping, optional
        How a reader maps texels back to ratios (default: the texel is the ratio).

    Returns
    -------
    tuple of (dict, bytes)
        The JSON object and the buffer (4-byte aligned parts).

    Examples
    --------
    >>> from ultraglide import grating
    >>> document, buffer = gltf_document(grating(2.0, size_mm=(40, 20)))
    >>> document["asset"]["version"], document["extensionsUsed"], len(buffer) % 4
    ('2.0', ['MPEG_haptic_material'], 0)
    """
    mapping = mapping or TexelMapping()
    width_m, height_m = texture.width_mm / 1000.0, texture.height_mm / 1000.0
    positions = np.array([[0, height_m, 0], [width_m, height_m, 0], [0, 0, 0], [width_m, 0, 0]], np.float32)
    normals = np.array([[0, 0, 1]] * 4, np.float32)
    coords = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], np.float32)
    indices = np.array([0, 2, 1, 1, 2, 3], np.uint16)
    info = PngImagePlugin.PngInfo()
    info.add_itxt(CHUNK, json.dumps(metadata_of(texture), ensure_ascii=False))
    friction_png = _png(Image.fromarray(quantise(mapping.texel(texture.values))), info)
    preview = Image.fromarray(preview_rgb(texture.ratio_map()), "RGB")
    if max(preview.size) > PREVIEW_SIDE:  # a picture for viewers: its detail is the friction texture's
        scale = PREVIEW_SIDE / max(preview.size)
        preview = preview.resize((max(1, round(preview.width * scale)), max(1, round(preview.height * scale))),
                                 Image.Resampling.BOX)
    preview_png = _png(preview)
    parts = [positions.tobytes(), normals.tobytes(), coords.tobytes(), indices.tobytes(), friction_png,
             preview_png]
    views, blob = [], bytearray()
    for part in parts:
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(part)})
        blob.extend(part)
    blob.extend(b"\0" * (-len(blob) % 4))
    for view in views[:3]:
        view["target"] = 34962  # ARRAY_BUFFER
    views[3]["target"] = 34963  # ELEMENT_ARRAY_BUFFER
    wrap = 10497 if texture.outside == "tile" else 33071  # REPEAT, CLAMP_TO_EDGE
    name = texture.name or "texture"
    document = {
        "asset": {"version": "2.0", "generator": "ultraglide texture export-gltf"},
        "extensionsUsed": [EXTENSION],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                                  "indices": 3, "material": 0}],
                    "extensions": {EXTENSION: {"hapticMaterialIndex": 0}}}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [float(np.float32(width_m)), float(np.float32(height_m)), 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
        "images": [{"bufferView": 4, "mimeType": "image/png", "name": f"{name} friction"},
                   {"bufferView": 5, "mimeType": "image/png", "name": f"{name} preview"}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": wrap, "wrapT": wrap},
                     {"magFilter": 9729, "minFilter": 9729, "wrapS": wrap, "wrapT": wrap}],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}],
        "materials": [{"name": name, "pbrMetallicRoughness": {"baseColorTexture": {"index": 1},
                                                               "metallicFactor": 0.0, "roughnessFactor": 0.9}}],
        "extensions": {EXTENSION: {"materials": [{"name": name, "friction": [
            {"texture": {"index": 0}, "type": "High_Resolution"}]}]}},
    }
    return document, bytes(blob)


def write_gltf(texture: Texture, path: str | os.PathLike, mapping: TexelMapping | None = None) -> Path:
    """Write ``texture`` as a glTF scene, atomically.

    A ``.glb`` (one binary file) or a ``.gltf`` (JSON, its buffer a data URI).

    Parameters
    ----------
    texture : Texture
        The friction map (a gradient texture's friction under a left-to-right swipe is its preview; its map,
        the height, is what the friction texture holds, with its metadata).
    path : str or path-like
        Ends in ``.glb`` or ``.gltf``.
    mapping : TexelMapping, optional
        How a reader maps texels back to ratios (default: the texel is the ratio).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TextureError
        The path does not end in ``.glb`` or ``.gltf``.

    Examples
    --------
    Written and read back at its size:

    >>> import pathlib, tempfile
    >>> from ultraglide import grating
    >>> path = write_gltf(grating(2.0, size_mm=(40, 20)), pathlib.Path(tempfile.mkdtemp()) / "grating.glb")
    >>> path.name, round(load_friction_texture(path).width_mm, 3)
    ('grating.glb', 40.0)
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".glb", ".gltf"):
        raise TextureError(f"{path}: a glTF scene is written to a .glb or a .gltf file")
    document, blob = gltf_document(texture, mapping)
    if suffix == ".gltf":
        document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
        data = json.dumps(document, indent=1).encode()
    else:
        text = json.dumps(document, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        total = 12 + 8 + len(text) + 8 + len(blob)
        data = b"".join([struct.pack("<4sII", GLB_MAGIC, 2, total), struct.pack("<II", len(text), CHUNK_JSON),
                         text, struct.pack("<II", len(blob), CHUNK_BIN), blob])
    with AtomicFile(path) as target, open(target.temporary, "wb") as stream:
        stream.write(data)
    return path


def warn_unused(scene: Scene, chosen: HapticMaterial) -> None:
    """Say what of a haptic material a friction display does not render (its other properties), as a warning.

    Parameters
    ----------
    scene : Scene
    chosen : HapticMaterial

    Returns
    -------
    None

    Examples
    --------
    >>> import dataclasses, pathlib, tempfile, warnings
    >>> from ultraglide import grating
    >>> scene = read_scene(write_gltf(grating(2.0), pathlib.Path(tempfile.mkdtemp()) / "grating.glb"))
    >>> stiff = dataclasses.replace(scene.materials[0], properties=("friction", "stiffness"))
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warn_unused(scene, stiff)
    >>> str(caught[0].message)
    ".../grating.glb: haptic material 0's stiffness textures are not rendered (a friction display renders
    friction only)"
    """
    others = [prop for prop in chosen.properties if prop != "friction"]
    if others:
        warnings.warn(f"{scene.path}: haptic material {chosen.index}'s {', '.join(others)} textures are not "
                      "rendered (a friction display renders friction only)", stacklevel=2)
