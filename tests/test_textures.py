"""Textures: sampling by hand, band limiting, gradients, procedural patterns, the file format."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, run_cli
from PIL import Image
from ultraglide.textures import procedural
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture, save_texture
from ultraglide.textures.library import LIBRARY_DIR, library_entries, resolve_texture
from ultraglide.textures.sampling import Sampler
from ultraglide.textures.seams import measure_seams
from ultraglide.textures.texture import Texture

# 2 × 2 pixels of 1 mm: centres at x = 0.5, 1.5 and y = 0.5, 1.5
SMALL = np.array([[0.0, 1.0], [0.5, 0.25]], dtype=np.float32)


def small(outside="clamp", **kw):
    return Texture(SMALL, 2.0, 2.0, outside=outside, **kw)


def test_bilinear_by_hand():
    sampler = Sampler(small())
    x = np.array([0.5, 1.5, 1.0, 1.0, 0.75])
    y = np.array([0.5, 1.5, 0.5, 1.0, 1.25])
    # centre values; midway on the top row: 0.5; the middle: mean of four = 0.4375;
    # (0.75, 1.25): fu = 0.25, fv = 0.75: top 0.25, bottom 0.5 - 0.0625 = 0.4375 → 0.25 + 0.75 × 0.1875
    expected = [0.0, 0.25, 0.5, 0.4375, 0.25 + 0.75 * 0.1875]
    assert sampler.ratio(x, y) == pytest.approx(expected, abs=1e-6)


def test_outside_rules():
    x = np.array([-0.5, 2.5, 3.5])
    y = np.array([0.5, 0.5, 1.5])
    # clamp: the edge pixel's value continues
    assert Sampler(small("clamp")).ratio(x, y) == pytest.approx([0.0, 1.0, 0.25])
    # tile: x = -0.5 is x = 1.5 of the copy to the left; 2.5 is 0.5; 3.5 is 1.5
    assert Sampler(small("tile")).ratio(x, y) == pytest.approx([1.0, 0.0, 0.25])
    # fixed: everything beyond the edges is the fixed ratio
    fixed = Sampler(small("fixed", outside_ratio=0.7)).ratio(np.append(x, 1.0), np.append(y, 1.0))
    assert fixed == pytest.approx([0.7, 0.7, 0.7, 0.4375])


def test_tiling_wraps_between_last_and_first_pixel():
    # halfway between the last centre (1.5) and the next tile's first (2.5): mean of 1.0 and 0.0
    assert Sampler(small("tile")).ratio([2.0], [0.5]) == pytest.approx([0.5])


def test_grating_period_and_values():
    texture = procedural.grating(2.0, size_mm=(20, 10), ratio_range=(0.2, 1.0))
    sampler = Sampler(texture)
    x = np.array([0.0, 1.0, 0.5, 2.0, 19.0])
    expected = 0.2 + 0.8 * (0.5 + 0.5 * np.cos(2 * np.pi * x / 2.0))
    assert sampler.ratio(x, np.full(5, 5.0)) == pytest.approx(expected, abs=5e-3)


def _spurious_low_frequency(sampler, step_mm):
    x = np.arange(2000) * step_mm + 0.3
    signal = sampler.ratio(x, np.full_like(x, 25.0), step_mm=step_mm)
    return np.std(signal)


def test_fast_swipe_over_fine_grating_does_not_alias():
    # a 0.25 mm grating read every 0.95 mm: point sampling folds 4 cycles/mm down to a strong
    # tone at 0.21 cycles/mm; the band-limited lookup leaves only the mean
    grating = procedural.grating(0.25, size_mm=(80, 50), ratio_range=(0.0, 1.0))
    naive = Sampler(grating, band_limited=False)
    limited = Sampler(grating)
    x = np.arange(2000) * 0.95 + 0.3
    y = np.full_like(x, 25.0)
    aliased = naive.ratio(x, y, step_mm=0.95)
    spectrum = np.abs(np.fft.rfft(aliased - aliased.mean())) / len(x)
    assert spectrum.max() > 0.15  # the naive lookup really aliases: a tone of amplitude ~0.5
    clean = limited.ratio(x, y, step_mm=0.95)
    assert np.std(clean) < 0.02
    assert np.mean(clean) == pytest.approx(0.5, abs=0.02)


def test_band_limiting_keeps_detail_the_sampling_can_follow():
    grating = procedural.grating(4.0, size_mm=(80, 50), ratio_range=(0.0, 1.0))
    x = np.arange(4000) * 0.05
    y = np.full_like(x, 25.0)
    limited = Sampler(grating).ratio(x, y, step_mm=0.05)
    exact = 0.5 + 0.5 * np.cos(2 * np.pi * x / 4.0)
    assert np.max(np.abs(limited - exact)) < 0.01


def test_gradient_bump_feels_like_a_bump_from_every_direction():
    texture = procedural.bumps(pitch_mm=20, diameter_mm=16, size_mm=(40, 40), ratio_range=(0.2, 1.0))
    sampler = Sampler(texture)
    centre = np.array([10.0, 10.0])
    for angle in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        before = centre - 4 * direction  # climbing the near side
        after = centre + 4 * direction  # descending the far side
        d = ([direction[0]], [direction[1]])
        up = sampler.ratio([before[0]], [before[1]], direction=d)[0]
        down = sampler.ratio([after[0]], [after[1]], direction=d)[0]
        top = sampler.ratio([centre[0]], [centre[1]], direction=d)[0]
        assert up > 0.8 and down < 0.4
        assert top == pytest.approx(0.6, abs=0.02)  # flat at the summit: the middle of the range


def test_procedural_generators_all_make_valid_textures():
    for name, generator in procedural.GENERATORS.items():
        texture = generator()
        assert texture.values.min() >= 0 and texture.values.max() <= 1, name
        assert texture.width_mm > 0 and texture.description


def test_chirp_wavelength_sweeps():
    texture = procedural.chirp(4.0, 1.0, size_mm=(60, 10), ratio_range=(0, 1))
    x = np.linspace(0, 60, 24000, endpoint=False)
    row = Sampler(texture).ratio(x, np.full_like(x, 5.0))
    crossings = np.flatnonzero(np.diff(np.sign(row - 0.5)) != 0)
    spacing = np.diff(x[crossings]) * 2  # two crossings a wavelength
    assert spacing[0] == pytest.approx(4.0, rel=0.1) and spacing[-1] == pytest.approx(1.0, rel=0.1)


@pytest.mark.parametrize("bad", [dict(wavelength_mm=0), dict(wavelength_mm=-1), dict(size_mm=(0, 10)),
                                 dict(ratio_range=(0.5, 0.2)), dict(ratio_range=(-0.1, 1)), dict(shape="saw")])
def test_procedural_bad_parameters(bad):
    with pytest.raises(TextureError):
        procedural.grating(**bad)


def test_file_round_trip_is_exact_to_16_bits(tmp_path):
    texture = procedural.noise(1.0, size_mm=(30, 20), seed=3)
    path = save_texture(texture, tmp_path / "n.png")
    loaded = load_texture(path)
    assert np.max(np.abs(loaded.values - texture.values)) <= 0.5 / 65535 + 1e-7
    again = load_texture(save_texture(loaded, tmp_path / "n2.png"))
    assert np.array_equal(again.values, loaded.values)
    for field in ("width_mm", "height_mm", "kind", "outside", "ratio_range", "name", "description", "authoring"):
        assert getattr(loaded, field) == getattr(texture, field), field
    with Image.open(path) as image:  # any viewer sees a 16-bit grayscale PNG
        assert image.format == "PNG" and image.mode.startswith("I")
        meta = json.loads(image.info["ultraglide"])
        assert meta["format_version"] == 1


def test_gradient_texture_round_trip(tmp_path):
    texture = procedural.bumps()
    loaded = load_texture(save_texture(texture, tmp_path / "b.png"))
    assert loaded.kind == "gradient"
    assert loaded.full_slope_per_mm == pytest.approx(texture.full_slope_per_mm)


def test_plain_png_loads_with_defaults_and_a_warning(tmp_path):
    path = tmp_path / "plain.png"
    Image.fromarray(np.full((20, 30), 128, np.uint8)).save(path)
    with pytest.warns(UserWarning, match="no ultraglide metadata"):
        texture = load_texture(path)
    assert texture.width_mm == pytest.approx(3.0)  # 10 px/mm
    assert texture.values.max() == pytest.approx(128 / 255)


@pytest.mark.parametrize("meta, message", [
    ({"format_version": 99, "width_mm": 1, "height_mm": 1}, "version"),
    ({"format_version": 1, "width_mm": -1, "height_mm": 1}, "width_mm"),
    ({"format_version": 1, "width_mm": 1, "height_mm": 1, "kind": "velvet"}, "kind"),
])
def test_bad_metadata_is_explained(tmp_path, meta, message):
    from PIL import PngImagePlugin
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", json.dumps(meta))
    path = tmp_path / "bad.png"
    Image.fromarray(np.zeros((4, 4), np.uint16)).save(path, pnginfo=info)
    with pytest.raises(TextureError, match=message):
        load_texture(path)


def test_library_has_the_promised_textures():
    entries = {entry.name: entry for entry in library_entries()}
    assert len(entries) >= 10
    for wanted in ("grating-1mm", "checkerboard-5mm", "noise-2mm", "bumps", "button", "slider", "wood", "fabric"):
        assert wanted in entries
    assert resolve_texture("grating-1mm").width_mm == 80.0
    with pytest.raises(TextureError, match="library"):
        resolve_texture("no-such-texture")


# ---- seamless tiles -------------------------------------------------------------------------------

TILING_CASES = {  # generators and parameters whose textures repeat; odd sizes and angles on purpose
    "grating": dict(wavelength_mm=2.0),
    "grating-45": dict(wavelength_mm=2.0, angle_deg=45),
    "grating-30-square-duty": dict(wavelength_mm=3.0, angle_deg=30, shape="square", duty=0.3),
    "grating-100": dict(wavelength_mm=1.7, angle_deg=100, size_mm=(37, 23)),
    "checkerboard": dict(square_mm=3.0, size_mm=(41, 29)),
    "dots": dict(pitch_mm=4.0, diameter_mm=2.0, size_mm=(50, 33)),
    "bumps": dict(pitch_mm=7.0, diameter_mm=5.0, size_mm=(45, 30)),
    "noise": dict(cutoff_mm=2.0),
    "fractal": dict(hurst=0.4),
}


def _generator(case):
    return procedural.GENERATORS[case.split("-")[0]]


@pytest.mark.parametrize("case", TILING_CASES)
def test_tiling_procedural_textures_have_no_seam(case):
    texture = _generator(case)(**TILING_CASES[case])
    assert texture.outside == "tile"
    report = measure_seams(texture.values)
    # the step across the tile's edge is no larger than the largest step between neighbours inside
    assert report.seam_max <= report.interior_max + 1e-6, (case, report)
    assert not report.visible, (case, report)


@pytest.mark.parametrize("case", [c for c in TILING_CASES if c.startswith("grating")])
def test_a_snapped_grating_repeated_is_its_exact_pattern_made_larger(case):
    # periodic within the tile: 2 × 2 copies equal the unsnapped grating of the realised wavelength and
    # angle generated over twice the size
    params = dict(TILING_CASES[case])
    width, height = params.pop("size_mm", procedural.DEFAULT_SIZE_MM)
    tile = procedural.grating(size_mm=(width, height), px_per_mm=10, **params)
    params.update(wavelength_mm=tile.authoring["tile_wavelength_mm"], angle_deg=tile.authoring["tile_angle_deg"])
    double = procedural.grating(size_mm=(2 * width, 2 * height), px_per_mm=10, tile=False, **params)
    mismatch = np.abs(np.tile(tile.values, (2, 2)) - double.values)
    assert np.mean(mismatch > 1e-3) < 1e-3  # square gratings may flip a pixel lying exactly on an edge


@pytest.mark.parametrize("kind, params", [("checkerboard", dict(square_mm=3.0)), ("dots", dict(pitch_mm=4.0)),
                                          ("bumps", dict(pitch_mm=7.0, diameter_mm=5.0))])
def test_lattices_repeat_exactly(kind, params):
    # sides that hold whole periods (84 and 42 mm hold 6, 4 and 7 mm periods): the pattern over twice
    # the size is the tile repeated
    size = (84, 48) if kind == "dots" else (84, 42)
    tile = procedural.GENERATORS[kind](size_mm=size, px_per_mm=10, **params)
    double = procedural.GENERATORS[kind](size_mm=(2 * size[0], 2 * size[1]), px_per_mm=10, **params)
    assert np.max(np.abs(np.tile(tile.values, (2, 2)) - double.values)) < 1e-4


def test_an_unsnapped_diagonal_grating_jumps_at_its_seam():
    # what the issue reported: 0.30-0.38 of relative friction at the seam of the 2 mm diagonal grating
    exact = procedural.grating(2.0, angle_deg=45, tile=False)
    assert exact.outside == "clamp" and exact.authoring["tile_wavelength_mm"] == pytest.approx(2.0)
    report = measure_seams(exact.values)
    assert report.seam_max > 0.3 and report.seam_max > 5 * report.interior_max
    assert report.visible


def test_grating_snaps_to_whole_cycles_and_says_so():
    texture = procedural.grating(2.0, size_mm=(80, 50), angle_deg=45)
    wavelength, angle = texture.authoring["tile_wavelength_mm"], texture.authoring["tile_angle_deg"]
    # whole cycles across each side: 80 cos(θ)/λ and 50 sin(θ)/λ are integers (28 and 18)
    cycles_x = 80 * np.cos(np.deg2rad(angle)) / wavelength
    cycles_y = 50 * np.sin(np.deg2rad(angle)) / wavelength
    assert cycles_x == pytest.approx(28) and cycles_y == pytest.approx(18)
    assert wavelength == pytest.approx(1 / np.hypot(28 / 80, 18 / 50)) and abs(wavelength - 2.0) < 0.05
    assert "snapped" in texture.description
    assert "snapped" not in procedural.grating(1.0).description  # 80 whole cycles already


def test_square_grating_duty_cycle():
    texture = procedural.grating(2.0, size_mm=(20, 4), shape="square", duty=0.25, ratio_range=(0.0, 1.0), px_per_mm=40)
    assert texture.values.mean() == pytest.approx(0.25, abs=0.01)
    # sticky for a quarter period around each crest (x = 0, 2, 4 ...): x = 0.2 sticky, x = 0.3 not
    sampler = Sampler(texture, band_limited=False)
    assert list(sampler.ratio([0.2, 0.3, 2.2, 1.0], [2, 2, 2, 2])) == [1.0, 0.0, 1.0, 0.0]


def test_fractal_spectrum_follows_its_hurst_exponent():
    # a fractional Brownian surface has radial power P(f) ∝ f^-(2H + 2)
    for hurst in (0.3, 0.8):
        texture = procedural.fractal(hurst, cutoff_mm=0.5, size_mm=(64, 64), px_per_mm=8, seed=4,
                                     ratio_range=(0, 1))
        power = np.abs(np.fft.fft2(texture.values - texture.values.mean())) ** 2
        fy = np.fft.fftfreq(texture.rows, d=64 / texture.rows)[:, None]
        fx = np.fft.fftfreq(texture.cols, d=64 / texture.cols)[None, :]
        f = np.hypot(fx, fy)
        bands = np.geomspace(0.05, 1.5, 12)
        centres, means = [], []
        for low, high in zip(bands[:-1], bands[1:], strict=True):
            pick = (f >= low) & (f < high)
            centres.append(np.sqrt(low * high))
            means.append(power[pick].mean())
        slope = np.polyfit(np.log(centres), np.log(means), 1)[0]
        assert slope == pytest.approx(-(2 * hurst + 2), abs=0.25), hurst
    with pytest.raises(TextureError, match="Hurst"):
        procedural.fractal(1.2)


def test_single_features_by_hand():
    gabor = Sampler(procedural.gabor(2.0, sigma_mm=4.0, size_mm=(30, 30), ratio_range=(0.2, 1.0)),
                    band_limited=False)
    # centre: crest under a full window → 1.0; half a wavelength off: trough at exp(-1/32) of the swing;
    # far away: the window is zero → middle of the range, and outside the texture too
    x = np.array([15.0, 16.0, 15.0, 40.0])
    y = np.array([15.0, 15.0, 29.9, 15.0])
    expected = [1.0, 0.6 - 0.4 * np.exp(-1 / 32), 0.6, 0.6]
    assert gabor.ratio(x, y) == pytest.approx(expected, abs=0.01)
    edge = Sampler(procedural.edge(0.5, size_mm=(40, 30), ratio_range=(0.2, 1.0)), band_limited=False)
    assert edge.ratio([5, 19.7, 20.0, 20.3, 35, 60], [15] * 6) == pytest.approx([0.2, 0.2, 0.6, 1.0, 1.0, 1.0],
                                                                                abs=0.03)
    lines = procedural.lines((1.0, 2.0), spacing_mm=10, size_mm=(40, 10), ratio_range=(0.2, 1.0), px_per_mm=20)
    row = Sampler(lines, band_limited=False).ratio([15.0, 15.6, 25.0, 25.9, 20.0, -5.0], [5] * 6)
    assert row == pytest.approx([1.0, 0.2, 1.0, 1.0, 0.2, 0.2], abs=0.01)  # lines at 15 (1 mm) and 25 (2 mm)
    bump = procedural.bump(10.0, size_mm=(30, 30))
    assert bump.kind == "gradient" and bump.values.max() == pytest.approx(1.0, abs=0.01)
    assert bump.values[0, 0] == 0.0 and bump.outside == "fixed" and bump.outside_ratio == pytest.approx(0.7)


# ---- the bundled library --------------------------------------------------------------------------

DOCS = Path(__file__).resolve().parent.parent / "docs"


def _documented_names():
    text = (DOCS / "textures.md").read_text()
    return re.findall(r"^\| !\[[^]]*\]\(textures/[^)]+\.png\) \| `([^`]+)` \|", text, flags=re.MULTILINE)


def test_library_listing_matches_the_files_and_the_docs():
    files = sorted(path.stem for path in LIBRARY_DIR.glob("*.png"))
    listed = [entry["name"] for entry in json.loads(run_cli("textures", "--json", check=True).stdout)]
    documented = _documented_names()
    thumbnails = sorted(path.stem for path in (DOCS / "textures").glob("*.png"))
    assert len(files) >= 20
    assert sorted(listed) == files and len(set(listed)) == len(listed)  # every file, once
    assert sorted(documented) == files  # and the docs describe exactly these
    assert thumbnails == files
    for name in files:
        assert (DOCS / "textures" / f"{name}.png").stat().st_size <= 10_500, name


def test_library_covers_what_researchers_use():
    textures = [resolve_texture(name) for name in _documented_names()]
    generators = {t.authoring.get("generator") for t in textures}
    assert {"grating", "checkerboard", "dots", "fractal", "gabor", "bump", "edge", "lines", "button", "slider",
            "toggle"} <= generators
    gratings = [t for t in textures if t.authoring.get("generator") == "grating"]
    assert {t.authoring["shape"] for t in gratings} == {"sine", "square"}
    assert len({t.authoring["wavelength_mm"] for t in gratings}) >= 3
    assert len({t.authoring["duty"] for t in gratings if t.authoring["shape"] == "square"}) >= 3
    assert len({t.authoring["hurst"] for t in textures if t.authoring.get("generator") == "fractal"}) >= 2


@pytest.mark.parametrize("entry", library_entries(), ids=lambda e: e.name)
def test_every_bundled_texture_loads_is_described_and_tiles_seamlessly(entry):
    texture = resolve_texture(entry.name)
    assert texture.name == entry.name
    assert len(texture.description) > 10
    assert texture.width_mm > 0 and texture.height_mm > 0
    if texture.outside == "tile":
        report = measure_seams(texture.values)
        assert report.seam_max <= report.interior_max + 1e-6, report
        assert not report.visible


# ---- what a newcomer reads: the library's listing, its numbers, its names, its wood ---------------------------

def test_the_library_listing_keeps_its_columns_on_long_names():
    lines = run_cli("textures", check=True).stdout.splitlines()
    header, rows = lines[0], lines[1:]
    longest = max(library_entries(), key=lambda entry: len(entry.name))
    assert any(row.startswith(longest.name + "  ") for row in rows)  # the longest name has its two spaces
    size_end = header.index("size (mm)") + len("size (mm)")
    kind_at = header.index("kind")
    for row in rows:
        assert re.fullmatch(r"\d+\.\d × \d+\.\d", row[:size_end].split("  ")[-1].strip()), row
        assert row[size_end:kind_at] == "  " and row[kind_at:].split()[0] in ("friction", "gradient"), row


def test_json_numbers_carry_no_float_noise():
    """78.80000000000001 mm is 78.8 mm; 0.4000000059604645 (a float32 ratio) is 0.4: numbers as they mean."""
    noisy = re.compile(r"\d\.\d*(\d)\1{5,}\d*|\d\.\d{10,}")  # a run of repeated digits, or ten decimals and more
    for command in (["textures", "--json"], ["texture", "info", "fabric", "--json"],
                    ["texture", "info", "wood", "--json"], ["texture", "info", "bumps", "--json"]):
        text = run_cli(*command, check=True).stdout
        assert not noisy.search(text), (command, noisy.search(text).group())
    fabric = json.loads(run_cli("texture", "info", "fabric", "--json", check=True).stdout)
    assert fabric["height_mm"] == 23.333 and fabric["friction"]["min"] == 0.4


def test_a_misspelt_texture_gets_a_suggestion():
    with pytest.raises(TextureError, match=r"did you mean 'wood'\?"):
        resolve_texture("wod")
    with pytest.raises(TextureError, match="did you mean 'grating-1mm'"):
        resolve_texture("grating-1")
    with pytest.raises(TextureError, match="library: bump, bumps"):  # nothing close: the library, named
        resolve_texture("zzzzzz")


def test_a_share_of_the_time_is_never_said_as_none_when_it_happened():
    """play warned "0.0 % of the time the texture asked for less friction than ... reaches" for a few samples
    of a second's swipe: something that happened, said as nothing."""
    from ultraglide.apps.commands.output_report import share_words

    assert share_words(3 / 12400) == "under 0.1 %"
    assert share_words(0.0) == "0.0 %" and share_words(1.0) == "100.0 %"
    assert share_words(0.0005) == "0.1 %" and share_words(0.25) == "25.0 %"
    assert share_words(12399 / 12400) == "over 99.9 %"


def test_library_warnings_say_what_to_do_in_python_too(tmp_path):
    """Raised from the API, a warning that only named command-line flags would leave a script's author lost."""
    from ultraglide.textures import compose

    plain = tmp_path / "plain.png"
    Image.fromarray(np.zeros((20, 30), np.uint8)).save(plain)
    with pytest.warns(UserWarning, match="AuthoringOptions") as caught:
        resolve_texture(str(plain))
    assert "ultraglide author" in str(caught[0].message)
    seam = Texture(np.tile(np.linspace(0.2, 1.0, 40, dtype=np.float32), (20, 1)), 40.0, 20.0, outside="tile")
    with pytest.warns(UserWarning, match="tiles with a seam") as caught:
        compose.mix([seam, seam])
    words = str(caught[0].message)
    assert "AuthoringOptions(seamless=" in words and "outside='clamp'" in words and "--seamless" in words


def test_the_bundled_wood_tiles_without_a_smear_or_a_kink():
    """Cross-fading a photo that does not tile blended unrelated rings into a low-contrast band at its left
    (x < 8 mm: 0.65 of the contrast elsewhere), and a random-walk warp left a kink at 24.9 mm (its columns'
    steps 3.7 times their neighbours'). Rebuilt (scripts/build_library.py) from a source drawn as a tile."""
    from scipy.ndimage import median_filter

    wood = resolve_texture("wood")
    values = wood.values.astype(float)
    report = measure_seams(values)
    assert report.seamless and not report.visible and report.ratio < 1.5
    band = round(8.0 / wood.pixel_mm[0])
    contrast = values.std(axis=0)
    for start in range(0, wood.cols - band + 1, band):  # every 8 mm band has the contrast of the whole
        assert contrast[start:start + band].mean() == pytest.approx(contrast.mean(), rel=0.15), start
    steps = np.abs(np.diff(values, axis=1)).mean(axis=0)
    assert (steps / median_filter(steps, size=21, mode="wrap")).max() < 1.6  # no column stands out
    assert "cross-fade" not in wood.description and wood.authoring.get("seamless") is None


def _documented_library() -> list[str]:
    table = (ROOT / "docs" / "textures.md").read_text(encoding="utf-8")
    return re.findall(r"^\|[^|]*\| `([^`]+)` \|", table, flags=re.MULTILINE)


def test_every_documented_texture_is_bundled_and_listed_by_the_command():
    documented = _documented_library()
    assert len(documented) >= 20  # the page's table was read (29 textures when this was written)
    bundled = [entry.name for entry in library_entries()]
    assert len(documented) == len(set(documented)) and set(documented) == set(bundled)
    listed = run_cli("textures", check=True).stdout
    missing = [name for name in documented if not re.search(rf"(^|\s){re.escape(name)}(\s|$)", listed, re.M)]
    assert not missing, f"`ultraglide textures` does not list {missing}"
    for name in documented:  # each thumbnail the page shows exists
        assert (ROOT / "docs" / "textures" / f"{name}.png").is_file(), name
