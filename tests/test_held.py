"""A decoded friction map held at a texture's resolution: Pillow's box filter reproduced (within the half code
Pillow rounds to at each of its two passes), and a PNG decoded straight into an array equal to Pillow's own."""

import io

import numpy as np
import pytest
from PIL import Image


@pytest.mark.parametrize(("shape", "size"), [((41, 37), (20, 30)), ((4096, 64), (60, 4000)), ((97, 4096), (4000, 95)),
                                             ((300, 200), (199, 300)), ((8, 8), (3, 3)), ((5, 7), (7, 5))])
def test_the_held_map_is_pillows_box_resampling(shape, size):
    from ultraglide.textures.formats.held import held_map

    codes = np.random.default_rng(sum(shape)).integers(0, 65536, shape).astype(np.uint16)
    pillow = np.asarray(Image.fromarray(codes).resize(size, Image.Resampling.BOX)).astype(float)
    held = held_map(codes, size, 65535.0)
    assert held.dtype == np.float32 and held.shape == (size[1], size[0])
    assert np.max(np.abs(held * 65535.0 - pillow)) <= 1.01  # Pillow rounds to whole codes after each pass


def test_box_weights_by_hand():
    from ultraglide.textures.formats.held import box_weights

    # 5 samples into 2: spans (0, 2.5] and (2.5, 5] of sample centres 0.5 .. 4.5: {0, 1, 2} and {3, 4}
    np.testing.assert_allclose(box_weights(5, 2).toarray(), [[1 / 3, 1 / 3, 1 / 3, 0, 0], [0, 0, 0, 0.5, 0.5]])
    assert np.asarray(Image.fromarray(np.array([[3, 6, 9, 100, 200]], np.uint16)).resize(
        (2, 1), Image.Resampling.BOX)).tolist() == [[6, 150]]  # Pillow agrees
    # 8-bit codes over 255, no resampling: the codes themselves
    from ultraglide.textures.formats.held import held_map

    np.testing.assert_allclose(held_map(np.array([[0, 51, 255]], np.uint8), (3, 1), 255.0), [[0.0, 0.2, 1.0]])


@pytest.mark.parametrize("mode", ["I;16", "L", "RGB"])
def test_a_png_decoded_into_an_array_equals_pillows_own(mode):
    from ultraglide.textures.formats.gltf import _load_into_array

    rng = np.random.default_rng(7)
    if mode == "I;16":
        image = Image.fromarray(rng.integers(0, 65536, (300, 200)).astype(np.uint16))
    elif mode == "L":
        image = Image.fromarray(rng.integers(0, 256, (300, 200)).astype(np.uint8))
    else:
        image = Image.fromarray(rng.integers(0, 256, (300, 200, 3)).astype(np.uint8))
    stream = io.BytesIO()
    image.save(stream, format="PNG")
    expected = np.asarray(Image.open(io.BytesIO(stream.getvalue())))
    opened = Image.open(io.BytesIO(stream.getvalue()))
    codes = _load_into_array(opened)
    if mode == "RGB":
        assert codes is None  # not a gray map: loaded as usual by the caller
    else:
        assert codes is not None and codes.dtype == expected.dtype and np.array_equal(codes, expected)
