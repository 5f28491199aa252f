"""Bad input, by class (issue 10), and the streaming trajectory reader (issue 13).

Property tests throw random values at each loader (trajectory CSV, table CSV, texture metadata,
device URL, every numeric option through the real parser): each input loads cleanly, and then
satisfies the documented ranges written out here, or raises the loader's one error type with a
one-line message; never another exception, never a hang (sizes are bounded and each example
runs under an alarm). End-to-end cases run the real command and check for one line, a non-zero
exit and no output file.
"""

import argparse
import contextlib
import io
import json
import math
import signal
import struct
import tracemalloc
import zlib

import numpy as np
import pytest
import soundfile
from conftest import assert_one_line_error, run_cli
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from PIL import Image, PngImagePlugin
from scipy.interpolate import PchipInterpolator
from ultraglide.apps.cli.parser import build_parser
from ultraglide.apps.cli.types import texture_name
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.urls import parse_device_url
from ultraglide.render import touch_log
from ultraglide.render.errors import RenderError
from ultraglide.render.physics import csv_table
from ultraglide.render.physics.calibration import load_model
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.measurements import NOISE_BELOW_ZERO
from ultraglide.render.touch_log import check_touch_log, read_touch_log
from ultraglide.render.trajectory import RecordedTrajectory
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import load_texture

PROPERTY = settings(max_examples=120, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@contextlib.contextmanager
def no_hang(seconds=30):
    """Fail (rather than hang) if the block runs longer than ``seconds``."""
    def expire(signum, frame):
        raise AssertionError(f"still running after {seconds} s: a hang")
    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def one_line(error: Exception) -> str:
    message = str(error)
    assert message and "\n" not in message and "Traceback" not in message
    return message


# ---- random cells for CSV files ------------------------------------------------------------------

SPECIAL = ["nan", "inf", "-inf", "1e308", "-1e308", "1e300", "-0", "", "abc", "0x10", " 7 ", '"2.5"']
cell = st.one_of(st.floats(-1e4, 1e4, allow_nan=False).map(repr), st.floats(-100, 100).map(repr),
                 st.sampled_from(SPECIAL), st.integers(-10**6, 10**6).map(str))


def as_number(text: str):
    """What a cell means, by Python's own float (and the CSV rules: quotes, spaces); None if not a number."""
    text = text.strip().strip('"').strip()
    if not text or "_" in text:
        return None
    try:
        return float(text)
    except ValueError:
        return None


# ---- trajectory CSV -----------------------------------------------------------------------------------

TRAJECTORY_HEADERS = ["t_s,x_mm,y_mm", "t_s,x_mm,y_mm,force_n", "y_mm,t_s,x_mm", "t_s,x_mm", "time,x,y"]


def trajectory_expectation(header: str, rows: list[list[str]]) -> bool:
    """Whether the documented rules accept the file: the header names t_s, x_mm, y_mm; each row
    has every column; t_s within ±1e10 s and never going back, spanning two instants and at most
    a day; x_mm, y_mm within ±10 000 mm; force_n 0..50 N."""
    names = header.split(",")
    if not {"t_s", "x_mm", "y_mm"} <= set(names):
        return False
    limits = {"t_s": (-1e10, 1e10), "x_mm": (-1e4, 1e4), "y_mm": (-1e4, 1e4), "force_n": (0, 50)}
    times = []
    for row in rows:
        if len(row) < len(names):
            return False
        for name, text in zip(names, row, strict=False):
            value = as_number(text)
            low, high = limits[name]
            if value is None or not (math.isfinite(value) and low <= value <= high):
                return False
        times.append(as_number(row[names.index("t_s")]))
    if len(times) < 2 or any(b < a for a, b in zip(times, times[1:], strict=False)):
        return False
    return times[0] < times[-1] and times[-1] - times[0] <= 86_400


@st.composite
def trajectory_files(draw):
    """A header and rows of cells: mostly well-formed, with every kind of fault mixed in."""
    header = draw(st.sampled_from(TRAJECTORY_HEADERS))
    width = len(header.split(","))
    plain = st.floats(0, 50).map(repr)  # valid in every column
    lengths = st.sampled_from([width] * 6 + [width - 1, width + 1])
    rows = [[draw(st.one_of(plain, plain, plain, cell)) for _ in range(draw(lengths))]
            for _ in range(draw(st.integers(0, 8)))]
    if draw(st.booleans()) and "t_s" in header:  # make valid files common: times that increase
        column = header.split(",").index("t_s")
        for k, row in enumerate(rows):
            if len(row) > column:
                row[column] = f"{0.01 * k:.3f}"
    return header, rows


@PROPERTY
@given(trajectory_files())
def test_trajectory_loader_loads_or_says_one_line(tmp_path, drawn):
    header, rows = drawn
    width = len(header.split(","))
    path = tmp_path / "log.csv"
    path.write_text(header + "\n" + "".join(",".join(row[:width + 1]) + "\n" for row in rows))
    expected = trajectory_expectation(header, [row[:width + 1] for row in rows])
    with no_hang():
        try:
            trajectory = read_touch_log(path)
        except RenderError as error:
            assert str(path) in one_line(error)
            assert not expected, f"refused a valid file: {error}"
            return
    assert expected, f"accepted a file the rules refuse:\n{path.read_text()}"
    state = trajectory.state(np.linspace(trajectory.start_s, trajectory.end_s, 7))
    assert np.all(np.isfinite(state.x_mm)) and np.all(np.abs(state.x_mm) <= 1e4)


# ---- table CSV (measured friction) -----------------------------------------------------------------

@PROPERTY
@given(force_column=st.booleans(),
       rows=st.lists(st.tuples(st.one_of(st.floats(0, 8), st.floats(0, 1e-3),
                                                 st.sampled_from([-1.0, 1e308, math.nan, math.inf])),
                               st.one_of(st.floats(0.05, 1.1), st.sampled_from([0.0, 1.0, 1.5, math.nan])),
                               st.sampled_from([0.2, 0.5, 0.5, -1.0, 0.0, 60.0])),
                     max_size=10))
# found by this test beside the brake's work: a repeated amplitude's second value dropped, the rest flat
@example(force_column=True, rows=[(0.0, 1.0, 0.2), (1.0, 1.0, 0.2), (1.0, 0.5, 0.2)])
@example(force_column=False, rows=[(0.0, 1.0, 0.5), (1.0, 0.5, 0.5), (1.0, 1.0, 0.5)])
def test_table_loader_gives_a_usable_model_or_one_line(tmp_path, force_column, rows):
    path = tmp_path / "table.csv"
    header = "amplitude_um_pp,relative_friction" + (",force_n" if force_column else "")
    lines = [f"{a!r},{r!r}" + (f",{f!r}" if force_column else "") for a, r, f in rows]
    path.write_text(header + "\n" + "\n".join(lines) + "\n")
    with no_hang():
        try:
            model = load_model(f"table:{path}")
        except ModelError as error:
            assert str(path) in one_line(error)
            return
    # a clean load is a model that inverts: finite amplitudes within the table for every ratio
    assert all(0 <= a <= 100 and -NOISE_BELOW_ZERO <= r <= 1.2 for a, r, _ in rows)  # noise about 0 is clipped
    assert not force_column or all(0 < f <= 50 for _, _, f in rows)
    assert min(r for _, r, _ in rows) < 1  # a flat table was refused
    amplitude = model.amplitude_um_pp(np.linspace(0.0, 1.0, 11), 0.5, 6.0).amplitude_um_pp
    assert np.all(np.isfinite(amplitude)) and np.all((amplitude >= 0) & (amplitude <= 6.0 + 1e-9))


@pytest.mark.parametrize("content, fragment", [
    ("amplitude_um_pp,relative_friction\n0,1\n1,1\n2,1\n", "flat table"),
    ("amplitude_um_pp,relative_friction\n0,1\n1e308,0.5\n", "out of range"),
    ("amplitude_um_pp,relative_friction\n1,1\n1,0.5\n", "two different amplitudes"),
    ("amplitude_um_pp,relative_friction,force_n\n0,1,0.5\n1,0.5,1e308\n", "force_n is out of range"),
    ("amplitude_um_pp,relative_friction\n0,1\n1,nan\n", "not a finite number"),
])
def test_bad_tables_through_the_cli(tmp_path, content, fragment):
    path = tmp_path / "t.csv"
    path.write_text(content)
    line = assert_one_line_error(run_cli("model", "--model", f"table:{path}", "--ratio", "0.8"))
    assert fragment in line and f"{path}" in line


# ---- texture metadata ----------------------------------------------------------------------------

def png_bytes(chunk: bytes | None = None, text: str | None = None, size=(4, 3)) -> bytes:
    """A 16-bit grayscale PNG with our metadata as Pillow writes it (``text``) or a raw chunk."""
    buffer = io.BytesIO()
    info = PngImagePlugin.PngInfo()
    if text is not None:
        info.add_itxt("ultraglide", text)
    Image.fromarray(np.full(size[::-1], 40000, np.uint16)).save(buffer, "PNG", pnginfo=info)
    data = buffer.getvalue()
    if chunk is not None:
        cut = data.index(b"IDAT") - 4
        body = b"iTXt" + chunk
        data = data[:cut] + struct.pack(">I", len(chunk)) + body + struct.pack(">I", zlib.crc32(body)) + data[cut:]
    return data


json_value = st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(), st.text(max_size=5),
                       st.lists(st.floats(-2, 2), max_size=3), st.dictionaries(st.text(max_size=3), st.integers(),
                                                                              max_size=2))
META_KEYS = ["format_version", "kind", "width_mm", "height_mm", "outside", "outside_ratio", "ratio_range",
             "full_slope_per_mm", "name", "description", "authoring"]
GOOD_META = {"format_version": 1, "kind": "friction", "width_mm": 40.0, "height_mm": 30.0, "outside": "tile",
             "outside_ratio": 1.0, "ratio_range": [0.4, 1.0], "full_slope_per_mm": 0.0, "name": "t",
             "description": "", "authoring": {}}


@PROPERTY
@given(changes=st.dictionaries(st.sampled_from(META_KEYS),
                               st.one_of(json_value, st.sampled_from(["gradient", "clamp", 1, 2.5, [0.2, 0.9]])),
                               max_size=3),
       size=st.sampled_from([(4, 3), (1, 1), (1, 5)]))
def test_texture_metadata_loads_in_range_or_says_one_line(tmp_path, changes, size):
    meta = {**GOOD_META, **changes}
    path = tmp_path / "t.png"
    path.write_bytes(png_bytes(text=json.dumps(meta), size=size))
    with no_hang():
        try:
            texture = load_texture(path)
        except TextureError as error:
            assert str(path) in one_line(error)
            return
    # what loaded is what the file says, and lies in the documented ranges
    assert meta["format_version"] == 1 and type(meta["format_version"]) is int
    assert (texture.width_mm, texture.height_mm) == (meta["width_mm"], meta["height_mm"])
    assert 0 < texture.width_mm <= 10_000 and 0 < texture.height_mm <= 10_000
    assert texture.kind == meta["kind"] in ("friction", "gradient") and texture.outside == meta["outside"]
    assert 0 <= meta["outside_ratio"] <= 1 and list(texture.ratio_range) == meta["ratio_range"]
    assert math.isfinite(texture.full_slope_per_mm) and texture.full_slope_per_mm >= 0
    assert texture.name == meta["name"] and isinstance(meta["authoring"], dict)


@pytest.mark.parametrize("chunk, fragment", [
    (b"ultraglide\0\1\0\0\0not zlib at all", "metadata chunk is damaged"),
    (b"ultraglide\0\0\0\0\0\xff\xfe{}", "metadata chunk is damaged"),
    (b"ultraglide\0\0\0\0\0" + b"[" * 50_000 + b"]" * 50_000, "nested too deeply"),
    (b"ultraglide\0\1\0\0\0" + zlib.compress(b" " * 5_000_000), "decompresses to more than Pillow reads"),  # a bomb
    (b"ultraglide\0\0\0\0\0{\"format_version\": 1, \"width_mm\": NaN, \"height_mm\": 1}", "width_mm"),
])
def test_malformed_png_text_chunks_are_one_line_errors_in_the_cli(tmp_path, chunk, fragment):
    texture = tmp_path / "bad.png"
    texture.write_bytes(png_bytes(chunk=chunk))
    out = tmp_path / "out.wav"
    line = assert_one_line_error(run_cli("export", texture, "-o", out, "--duration-s", "0.1"))
    assert fragment in line
    assert not out.exists() and not list(tmp_path.glob(".out*"))


# ---- device URLs -----------------------------------------------------------------------------------

DOCUMENTED_OPTIONS = {  # README and devices/urls.py: each kind's keys and their ranges
    "sim": {}, "serial": {"baud": (50, 12_000_000), "rate": (1000, 12_000), "frame_ms": (1, 20)},
    "audio": {"rate": (8_000, 768_000), "latency": (0, 10), "blocksize": (0, 65_536)},
    "wav": {"rate": (12_000, 768_000)}, "null": {"rate": (12_000, 768_000)},
}
url_value = st.one_of(st.integers(-10, 10**7).map(str), st.floats().map(repr),
                      st.sampled_from(["", "low", "high", "1e9", "96000", "0.01", "abc", "nan"]))


@st.composite
def device_urls(draw):
    """URLs mostly of the right shape (a kind, its target, its own keys), with faults mixed in."""
    kind = draw(st.sampled_from([*DOCUMENTED_OPTIONS, *DOCUMENTED_OPTIONS, "bluetooth", ""]))
    fitting = {"serial": ":/dev/ttyUSB0", "wav": ":out.wav", "audio": ":2"}.get(kind, "")
    target = draw(st.sampled_from([fitting] * 4 + ["", ":", ":x:y"]))
    keys = st.sampled_from([*DOCUMENTED_OPTIONS.get(kind, {})] * 3 + ["rate", "baud", "x", ""])
    pairs = draw(st.lists(st.tuples(keys, url_value), max_size=3))
    query = "&".join(f"{key}={value}" for key, value in pairs)
    query += draw(st.sampled_from([""] * 4 + ["&", "&flag", "=1"])) if pairs else ""
    return f"{kind}{target}" + (f"?{query}" if query else "")


@PROPERTY
@given(url=device_urls())
def test_device_urls_parse_in_range_or_say_one_line(url):
    with no_hang():
        try:
            spec = parse_device_url(url)
        except DeviceError as error:
            one_line(error)
            return
    allowed = DOCUMENTED_OPTIONS[spec.kind]
    assert set(spec.options) <= set(allowed)
    for key, value in spec.options.items():
        if value in ("low", "high"):
            assert key == "latency"
            continue
        low, high = allowed[key]
        assert math.isfinite(value) and low <= value <= high
    if spec.kind in ("sim", "null"):
        assert spec.target == ""
    if spec.kind in ("serial", "wav"):
        assert spec.target


def test_unknown_url_keys_and_absurd_rates_are_refused():
    for url, fragment in [("sim?x=y", "unknown option 'x' for sim"), ("wav:a.wav?rate=0", "rate must be"),
                          ("wav:?rate=0", "wav needs a path"), ("null?rate=96000&rate=1", "given twice"),
                          ("audio?latency=nan", "latency"), ("serial:/dev/x?baud=-1", "baud"), ("sim:x", "no port"),
                          ("null?rate", "KEY=VALUE")]:
        with pytest.raises(DeviceError, match=fragment):
            parse_device_url(url)


# ---- every numeric option through the real parser --------------------------------------------------

# The documented range of every option that is not free text:
# (low, high, low excluded, whole number, high excluded); OVERRIDES where a flag means another thing.
FEATURE = (0.01, 10_000, False, False, False)
RANGES = {
    "--force": (0, 10, True, False, False), "--preload-n": (0, 10, False, False, False),
    "--ratio": (0, 1, True, False, False),
    "--screen-width-mm": (10, 10_000, False, False, False), "--range": (0, 1, False, False, False),
    "--levels": (0, 1, False, False, False), "--width-mm": (0.1, 10_000, False, False, False),
    "--dpi": (1, 100_000, False, False, False), "--gamma": (0.01, 100, False, False, False),
    "--blur-mm": (0, 1000, False, False, False), "--max-pixels": (1, 100_000_000, False, True, False),
    "--px-per-mm": (0.1, 1000, False, False, False), "--angle-deg": (-360, 360, False, False, False),
    "--direction-deg": (-360, 360, False, False, False), "--seed": (0, 2**32 - 1, False, True, False),
    "--detents": (1, 100, False, True, False), "--speed-mm-s": (0, 10_000, True, False, False),
    "--duration-s": (0, 3600, True, False, False), "--radius-mm": (0, 10_000, True, False, False),
    "--zigzag-width-mm": (0, 10_000, True, False, False), "--carrier-hz": (1000, 200_000, False, False, False),
    "--rate": (12_000, 768_000, False, True, False), "--lookahead-ms": (0, 1000, False, False, False),
    "--start": (-10_000, 10_000, False, False, False), "--size-mm": (0.1, 10_000, False, False, False),
"--resonance-hz": (1000, 200_000, False, False, False),
    "--q": (1, 100_000, False, False, False), "--drift-hz-per-s": (-10_000, 10_000, False, False, False),
    "--clock-ppm": (-50_000, 50_000, False, False, False),
    "--seam-band": (0, 0.5, True, False, False), "--auto-levels-clip": (0, 50, False, False, True),
    "--duty": (0, 1, True, False, True), "--hurst": (0, 1, True, False, True),
    "--weights": (0, 1e6, False, False, False), "--else-ratio": (0, 1, False, False, False),
    "--steps": (1, 10_000, False, True, False),
    "--trials": (1, 100_000, False, True, False), "--break-every": (0, 100_000, False, True, False),
    "--bootstrap": (10, 100_000, False, True, False), "--repeats": (1, 10_000, False, True, False),
    "--afc": (2, 3, False, True, False), "--start-level": (0, 10_000, False, False, False),
    "--threads": (1, 256, False, True, False),
    # the simulated finger (plate-sim, and the in-process sim of play, demo and calibrate)
    "--finger-scale": (0.1, 10, False, False, False), "--finger-floor": (0, 1, False, False, True),
    "--finger-mu0": (0.05, 5, False, False, False), "--finger-drift": (0, 0.9, False, False, False),
    "--finger-drift-period-s": (0.1, 3600, False, False, False), "--finger-moisture": (0, 2, False, False, False),
    "--finger-moisture-tau-s": (0.1, 3600, False, False, False),
    "--finger-speed-mm-s": (0, 2000, False, False, False), "--finger-noise-n": (0, 1, False, False, False),
    "--finger-bandwidth-hz": (0, 20_000, False, False, False), "--finger-delay-ms": (0, 100, False, False, False),
    "--finger-log-hz": (1, 48_000, False, False, False), "--finger-seed": (0, 2**32 - 1, False, True, False),
    # on-plate calibration
    "--forces": (0.05, 10, False, False, False), "--passes": (1, 10, False, True, False),
    "--step-ms": (100, 5000, False, False, False),
    "--sensor-bandwidth-hz": (0, 20_000, False, False, False), "--sensor-delay-ms": (0, 100, False, False, False),
    "--slide-speed-mm-s": (1, 2000, False, False, False),
    # the service and the formats
    "--port": (0, 65535, False, True, False), "--view-mm": (1, 2000, False, False, False),
    "--reconnect-timeout-s": (0.1, 86_400, False, False, False),
    "--texel-range": (0, 1, False, False, False),
    **{flag: FEATURE for flag in ("--wavelength-mm", "--square-mm", "--pitch-mm", "--diameter-mm", "--cutoff-mm",
                                  "--start-mm", "--end-mm", "--edge-mm", "--detent-mm", "--sigma-mm",
                                  "--widths-mm", "--spacing-mm")},
}
OVERRIDES = {(("texture", "show"), "--dpi"): (10, 2400, False, False, False),
             (("texture", "new", "edge"), "--width-mm"): FEATURE,
             (("plate", "sweep"), "--steps"): (5, 2000, False, True, False),
             (("experiment", "threshold"), "--range"): (0, 10_000, False, False, False),
             (("experiment", "constant"), "--range"): (0, 10_000, False, False, False),
             (("experiment", "constant"), "--levels"): (0, 10_000, False, False, False),
             (("plate", "sweep"), "--from-hz"): (1000, 200_000, False, False, False),
             (("plate", "sweep"), "--to-hz"): (1000, 200_000, False, False, False),
             (("plate", "sweep"), "--sensor-um-per-unit"): (1e-6, 1e6, False, False, False),
             (("calibrate",), "--bootstrap"): (0, 10_000, False, True, False),
             # a finger's sliding speed for the model's speed law: at rest (0) is a speed, said as held at 2 mm/s
             (("model",), "--speed-mm-s"): (0, 2000, False, False, False)}
TEXT_FORMS = ("--crop", "--region", "--finger-fault", "--participant",
              "--board-fault", "--token")  # typed text of their own form, tested where
# they belong (--participant: test_calibration_on_plate; --token: test_experiment_browser)
PAIRS = {"--start": ",", "--size-mm": "x"}  # two numbers in one argument
TAILS = {("author",): ["in.png", "-o", "o.png"], ("export",): ["g", "-o", "o.wav"], ("play",): ["g"],
         ("calibrate",): ["data.csv"], ("texture", "new"): ["-o", "o.png"], ("texture", "show"): ["g", "-o", "o.png"],
         ("texture", "info"): ["g"],
         ("texture", "compose", "mask"): ["a", "m", "-o", "o.png"],
         ("texture", "compose", "tile"): ["a", "b", "--region", "1,1,1,1", "-o", "o.png"],
         ("texture", "compose"): ["a", "b", "-o", "o.png"], ("plate", "sweep"): ["-o", "p.toml"],
         ("experiment",): ["--out", "o"], ("experiment", "run"): ["d.toml", "--participant", "P1", "--out", "o"],
         ("experiment", "check"): ["d.toml"], ("texture", "import"): ["scene.glb", "-o", "o.png"]}


def range_of(words, flag):
    return OVERRIDES.get((tuple(words), flag), RANGES.get(flag))


def tail_for(words):
    """The positional arguments and required options of a command, so that only the option under test varies."""
    for length in range(len(words), 0, -1):
        if tuple(words[:length]) in TAILS:
            return TAILS[tuple(words[:length])]
    return []


def typed_options(parser=None, prefix=()):
    """Every (command words, option action) whose value is typed, found by walking the real parser."""
    parser = parser or build_parser()
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                found += typed_options(sub, prefix + (name,))
        elif action.option_strings and action.type not in (None, str, texture_name):
            found.append((prefix, action))
    return found


OPTIONS = typed_options()


def test_every_typed_option_has_a_documented_range():
    missing = {(words, action.option_strings[-1]) for words, action in OPTIONS
               if action.option_strings[-1] not in TEXT_FORMS
               and range_of(words, action.option_strings[-1]) is None}
    assert not missing, f"options without a range here: {missing}"
    assert len(OPTIONS) > 60


number_text = st.one_of(st.floats().map(repr), st.integers(-10**12, 10**12).map(str),
                        st.sampled_from(["", "nan", "-inf", "1e308", "1e-300", "abc", "0", "-0", "5", "0.5"]))


@pytest.mark.slow
@PROPERTY
@given(choice=st.sampled_from(OPTIONS), first=number_text, second=number_text)
def test_numeric_options_parse_in_range_or_say_one_line(choice, first, second):
    words, action = choice
    flag = action.option_strings[-1]
    if flag in ("--crop", "--finger-fault", "--participant", "--board-fault",
                "--token"):  # whole pixels; KIND:START-END (test_closed_loop); an id (test_calibration_on_plate)
        return
    tail = tail_for(words)
    if action.nargs in (2, "+"):
        argv = [*words, *tail, flag, first, second]
    else:
        value = {"--start": f"{first},{second}", "--size-mm": f"{first}x{second}",
                 "--region": f"{first},{second},{second},{first}"}.get(flag, first)
        argv = [*words, *tail, f"{flag}={value}"]  # --flag=VALUE: a value may start with a minus
    stderr = io.StringIO()
    with no_hang(), contextlib.redirect_stderr(stderr):
        try:
            args = build_parser(argv).parse_args(argv)  # as main() parses
        except SystemExit as exit_:
            assert exit_.code == 2
            lines = stderr.getvalue().strip().splitlines()
            assert len(lines) == 1 and flag in lines[0], stderr.getvalue()
            return
    parsed = getattr(args, action.dest)
    values = list(parsed) if isinstance(parsed, list | tuple) else [parsed]
    if flag == "--region":  # X,Y within ±10 000 mm, the size positive up to 10 000 mm
        limits = [(-10_000, 10_000, False, False, False)] * 2 + [(0, 10_000, True, False, False)] * 2
    else:
        limits = [range_of(words, flag)] * len(values)
    for value, (low, high, low_open, whole, high_open) in zip(values, limits, strict=True):
        assert math.isfinite(value)
        assert (value > low if low_open else value >= low) and (value < high if high_open else value <= high)
        assert not whole or value == int(value)


# ---- issue 10's cases, end to end: one line, non-zero exit, no output --------------------------------

def test_one_pixel_image_in_gradient_mode(tmp_path):
    Image.new("L", (1, 1), 128).save(tmp_path / "one.png")
    out = tmp_path / "t.png"
    line = assert_one_line_error(run_cli("author", tmp_path / "one.png", "-o", out, "--mode", "gradient"))
    assert "2×2" in line and not out.exists()


@pytest.mark.parametrize("args, fragment", [
    (["--max-pixels", "1e308"], "--max-pixels"), (["--max-pixels", "0.5"], "--max-pixels"),
    (["--width-mm", "1e-300"], "--width-mm"), (["--width-mm", "1e308"], "--width-mm"),
    (["--blur-mm", "1e308"], "--blur-mm"), (["--blur-mm", "500"], "wider than the texture"),
    (["--dpi", "1"], "more than 10000 mm"),
])
def test_absurd_author_options(tmp_path, args, fragment):
    Image.fromarray(np.tile(np.arange(512) % 256, (48, 1)).astype(np.uint8)).save(tmp_path / "in.png")  # 512 px
    out = tmp_path / "t.png"
    line = assert_one_line_error(run_cli("author", tmp_path / "in.png", "-o", out, *args))
    assert fragment in line
    assert not out.exists() and not list(tmp_path.glob(".t*"))


@pytest.mark.parametrize("source, fragment", [("dir", "is a directory"), ("text", "not an image"),
                                              ("truncated", "damaged or truncated")])
def test_wrong_files_for_author(tmp_path, source, fragment):
    path = tmp_path / "in.png"
    if source == "dir":
        path.mkdir()
    elif source == "text":
        path.write_text("t_s,x_mm,y_mm\n")
    else:
        buffer = io.BytesIO()
        Image.fromarray(np.random.default_rng(0).integers(0, 255, (64, 64), dtype=np.uint8)).save(buffer, "PNG")
        path.write_bytes(buffer.getvalue()[:600])
    assert fragment in assert_one_line_error(run_cli("author", path, "-o", tmp_path / "t.png"))
    assert not (tmp_path / "t.png").exists()


@pytest.mark.parametrize("rows, fragment", [
    ("0,1,1\nnan,2,2\n", "t_s is not a finite number"),
    ("0,1,1\ninf,2,2\n", "t_s is not a finite number"),
    ("0,1,1\n1,2,2\n0.5,3,3\n", ":4: time goes backwards"),
    ("0,1,1\n1e300,2,2\n", "t_s is out of range"),
    ("0,1,1\n1e9,2,2\n", "more than a day"),
    ("0,1,1\n1,1e300,2\n", "x_mm is out of range"),
    ("0,1,1\n0,2,2\n", "same time"),
])
def test_absurd_trajectory_times_and_positions(tmp_path, rows, fragment):
    log = tmp_path / "log.csv"
    log.write_text("t_s,x_mm,y_mm\n" + rows)
    out = tmp_path / "out.wav"
    line = assert_one_line_error(run_cli("export", "grating-1mm", "--trajectory", log, "-o", out, timeout=60))
    assert fragment in line
    assert not out.exists() and not list(tmp_path.glob(".out*"))


def test_bad_device_urls_through_play(tmp_path):
    for url, fragment in [("wav:?rate=0", "needs a path"), (f"wav:{tmp_path / 'x.wav'}?rate=0", "rate must be"),
                          ("sim?x=y", "unknown option")]:
        assert fragment in assert_one_line_error(run_cli("play", "grating-1mm", "--device", url,
                                                         "--duration-s", "0.1"))
    assert not list(tmp_path.iterdir())


# ---- the streaming trajectory reader ---------------------------------------------------------------

def write_log(path, t, x, y, force=None, comment_every=0):
    lines = ["# logged", "t_s,x_mm,y_mm" + (",force_n" if force is not None else "")]
    for k in range(len(t)):
        if comment_every and k % comment_every == 0:
            lines.append("# a note" if k % 2 else "   ")
        row = ",".join(repr(float(v[k])) for v in (t, x, y) + ((force,) if force is not None else ()))
        lines.append(row)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow
def test_streamed_state_matches_whole_path_pchip_across_many_blocks(tmp_path, monkeypatch):
    monkeypatch.setattr(csv_table, "BLOCK_BYTES", 2048)  # dozens of blocks, so the window moves through them
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(1 / 240, 1 / 60, 3000))
    t[700] = t[699]  # a repeated instant: the later row stands
    x, y, force = np.cumsum(rng.normal(0, 1, 3000)), rng.uniform(0, 50, 3000), rng.uniform(0.1, 2, 3000)
    log = tmp_path / "log.csv"
    write_log(log, t, x, y, force, comment_every=97)
    trajectory = read_touch_log(log)
    keep = np.append(t[1:] != t[:-1], True)
    whole_x = PchipInterpolator(t[keep] - t[0], x[keep])
    whole_y = PchipInterpolator(t[keep] - t[0], y[keep])
    held = []
    start = 0.0
    while start <= trajectory.end_s:  # 1 s blocks at 12 kHz, as export pulls them
        times = start + np.arange(12000) / 12000.0
        state = trajectory.state(times)
        inside = times <= trajectory.end_s
        # numpy's comparisons: pytest.approx compares 12 000 values one at a time in Python (5 s of this test)
        np.testing.assert_allclose(state.x_mm[inside], whole_x(times[inside]), rtol=0, atol=1e-9)
        np.testing.assert_allclose(state.y_mm[inside], whole_y(times[inside]), rtol=0, atol=1e-9)
        np.testing.assert_allclose(state.force_n[inside], np.interp(times[inside], t[keep] - t[0], force[keep]),
                                   rtol=1e-6, atol=1e-12)
        assert not np.any(state.down[~inside])
        held.append(len(trajectory._t))
        start += 1.0
    assert max(held) < 400  # a window of records, never the 3000
    early = trajectory.state(np.array([0.5]))  # going back re-reads from the start
    assert early.x_mm[0] == pytest.approx(whole_x(0.5), abs=1e-9)


def test_errors_name_the_line_in_a_later_block(tmp_path, monkeypatch):
    monkeypatch.setattr(csv_table, "BLOCK_BYTES", 1024)
    t = np.arange(2000) * 0.01
    rows = [f"{v:.2f},1,1" for v in t]
    rows[1500] = "15.00,oops,1"
    log = tmp_path / "log.csv"
    log.write_text("t_s,x_mm,y_mm\n" + "\n".join(rows) + "\n")
    with pytest.raises(RenderError, match=r"log.csv:1502: x_mm is not a number: 'oops'"):
        check_touch_log(log)
    rows[1500] = "14.00,1,1"  # goes back, in the middle of a block
    log.write_text("t_s,x_mm,y_mm\n" + "\n".join(rows) + "\n")
    with pytest.raises(RenderError, match=r"log.csv:1502: time goes backwards \(14 s after 14.99 s\)"):
        check_touch_log(log)


def test_text_forms_a_logger_writes_are_read(tmp_path):
    log = tmp_path / "log.csv"
    log.write_bytes("\ufeff# exported\r\nx_mm,y_mm,t_s,extra\r\n\r\n1,2,\"0.5\",a\r\n 3 , 4 ,1.5,b\r\n".encode())
    trajectory = read_touch_log(log)
    assert trajectory.end_s == pytest.approx(1.0)
    state = trajectory.state(np.array([0.0, 1.0]))
    assert state.x_mm.tolist() == [1.0, 3.0] and state.y_mm.tolist() == [2.0, 4.0]


def test_not_text_and_endless_lines_are_refused(tmp_path):
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"t_s,x_mm,y_mm\n0,1,1\n\xff\xfe\x00\x01\n")
    with pytest.raises(RenderError, match="b.csv:3: not UTF-8 text"):
        check_touch_log(binary)
    endless = tmp_path / "e.csv"
    endless.write_bytes(b"t_s,x_mm,y_mm\n" + b"1" * (1 << 20))
    with no_hang(), pytest.raises(RenderError, match="line longer than"):
        check_touch_log(endless)
    with pytest.raises(RenderError, match="is a directory"):
        check_touch_log(tmp_path)


@pytest.mark.slow
def test_a_long_log_streams_in_bounded_memory(tmp_path):
    """400 k rows (12.8 MB as four float arrays, several times that as Python lists) render
    with a peak well under the size of the data."""
    rows = 400_000
    t = np.arange(rows) / 10_000.0
    log = tmp_path / "long.csv"
    with open(log, "w") as stream:
        stream.write("t_s,x_mm,y_mm,force_n\n")
        np.savetxt(stream, np.column_stack([t, 40 + 30 * np.sin(t), 25 + 0 * t, 0.5 + 0 * t]), fmt="%.3f",
                   delimiter=",")
    RecordedTrajectory([0.0, 1.0], [0.0, 1.0], [0.0, 1.0]).state(np.array([0.5]))  # compiled first, not counted
    tracemalloc.start()
    try:
        trajectory = read_touch_log(log)
        start = 0.0
        while start <= trajectory.end_s:
            state = trajectory.state(start + np.arange(12000) / 12000.0)
            start += 1.0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert state.x_mm[0] == pytest.approx(40 + 30 * np.sin(start - 1.0), abs=2e-3)
    assert peak < 6e6, f"peak {peak / 1e6:.1f} MB"  # measured 3.7 MB; the whole log would be 12.8 MB


def test_play_streams_a_touch_log_to_a_wav_device(tmp_path):
    t = np.arange(0, 1.5, 1 / 120)
    log = tmp_path / "log.csv"
    write_log(log, 100 + t, 10 + 100 * t, np.full(len(t), 25.0), np.full(len(t), 0.4))
    out = tmp_path / "live.wav"
    run_cli("play", "grating-2mm", "--trajectory", log, "--device", f"wav:{out}", check=True)
    samples, rate = soundfile.read(out)
    assert len(samples) / rate == pytest.approx(1.55, abs=0.15)
    segment = samples[rate // 4: rate // 4 + rate // 2]
    spectrum = np.abs(np.fft.rfft(segment * np.hanning(len(segment))))
    freqs = np.fft.rfftfreq(len(segment), 1 / rate)
    assert spectrum[np.argmin(abs(freqs - 25050))] > 0.1 * spectrum.max()  # 2 mm at 100 mm/s: 50 Hz


def test_a_short_log_is_read_once_and_a_change_after_its_check_does_not_reach_the_render(tmp_path):
    log = tmp_path / "log.csv"
    log.write_text("t_s,x_mm,y_mm\n0,1,1\n1,2,2\n2,3,3\n")
    trajectory = read_touch_log(log)
    log.write_text("t_s,x_mm,y_mm\n0,9,9\n2,9,9\n1,9,9\n")  # rewritten by a logger still running
    state = trajectory.state(np.array([0.0, 0.5, 2.0]))
    assert state.x_mm.tolist() == pytest.approx([1.0, 1.5, 3.0])  # the checked records, not the new ones


def test_a_long_log_changed_between_check_and_render_is_an_error(tmp_path, monkeypatch):
    monkeypatch.setattr(touch_log, "HELD_BYTES", 10)  # a log larger than is held: streamed, so read again
    log = tmp_path / "log.csv"
    log.write_text("t_s,x_mm,y_mm\n0,1,1\n1,2,2\n2,3,3\n")
    trajectory = read_touch_log(log)
    log.write_text("t_s,x_mm,y_mm\n0,1,1\n2,2,2\n1,3,3\n")  # rewritten by a logger still running
    with pytest.raises(RenderError, match="changed while it was being read"):
        trajectory.state(np.linspace(0, 2, 10))


def test_a_repeated_amplitude_counts_as_the_mean_of_its_readings(tmp_path):
    """Two readings at 1 µm p-p (1.0 and 0.5) are one point at 0.75: the inverse of 0.875 is halfway to it."""
    path = tmp_path / "t.csv"
    path.write_text("amplitude_um_pp,relative_friction\n0,1\n1,1\n1,0.5\n")
    model = load_model(f"table:{path}")
    assert model.relative_friction(1.0, 0.5) == pytest.approx(0.75, abs=1e-6)
    assert model.amplitude_um_pp(np.array([0.875]), 0.5, 6.0).amplitude_um_pp[0] == pytest.approx(0.5, abs=0.02)
