"""Hostile files (issue 26): whatever a file holds, every loader answers in one line of its own error type, in
bounded time and memory, and what the command prints is safe for a terminal and strict for a JSON parser.

By class: nesting 100 000 deep in every JSON and TOML file we read; integers of 5 000 digits (beyond Python's
int-string limit) and of 4 000 (within it, beyond a float); sizes that would make a later stage divide by zero;
a PNG of 99 million pixels; escape sequences and bidirectional overrides in a texture's text; a 10 MB profile of
unknown keys; every command's ``--json`` read back by a parser that refuses NaN and Infinity.
"""

import json
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli
from PIL import Image, PngImagePlugin
from test_inputs import no_hang
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.output import json_text, one_line, printable
from ultraglide.apps.experiment.log import read_session, read_trials
from ultraglide.apps.experiment.session import resumed_config
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.finger import ForceScript
from ultraglide.render.errors import RenderError
from ultraglide.render.physics.calibration import load_model, read_calibration
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.touch_log import read_touch_log
from ultraglide.textures.authoring import read_image_luminance
from ultraglide.textures.effects import load_effects
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import MAX_HELD_PIXELS, MAX_PX_PER_MM, load_texture
from ultraglide.textures.sampling import Sampler

from ultraglide.errors import UltraglideError

DEEP = 100_000
HUGE = "9" * 5_000  # more digits than Python turns into an int (4 300)
LARGE = "9" * 4_000  # an int Python reads, far beyond a float


def texture_png(path: Path, metadata: str, size=(20, 10), mode="L") -> Path:
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", metadata)
    Image.new(mode, size, 200).save(path, pnginfo=info)
    return path


def deep_json(inner: str = "1") -> str:
    return "[" * DEEP + inner + "]" * DEEP


def deep_toml(key: str) -> str:
    return f"{key} = " + "[" * DEEP + "1" + "]" * DEEP + "\n"


PROFILE = "resonance_hz = 25000\nq = 200\nfull_scale_um_pp = 8\nmax_amplitude_um_pp = 6\n"
CALIBRATION = 'ultraglide_calibration = 1\nmodel = "exponential"\n[parameters]\ntau_um_zp = 1.3\n'
EFFECTS = '{"effects_version": 1, "bindings": []}'
SESSION = '{"config": {"texture": "grating-1mm"}}'
TEXTURE = '{"format_version": 1, "width_mm": 20, "height_mm": 10}'

# what each loader is given: (load, error type, file name, writes the file's content)
LOADERS = {
    "texture": (load_texture, TextureError, "t.png", lambda path, text: texture_png(path, text)),
    "profile": (load_profile, DeviceError, "p.toml", lambda path, text: path.write_text(text)),
    "calibration": (read_calibration, ModelError, "c.toml", lambda path, text: path.write_text(text)),
    "effects": (load_effects, TextureError, "e.json", lambda path, text: path.write_text(text)),
    "session": (lambda path: resumed_config(read_session(path.parent), None, str(path)), UsageError, "session.json",
                lambda path, text: path.write_text(text)),
}
HOSTILE = {  # loader: its good text with one value made hostile, by class
    "deep": {"texture": TEXTURE[:-1] + ', "authoring": {"a": ' + deep_json() + "}}",
             "profile": PROFILE + deep_toml("description"),
             "calibration": CALIBRATION.replace("[parameters]", deep_toml("x") + "[parameters]"),
             "effects": EFFECTS[:-1] + ', "x": ' + deep_json() + "}",
             "session": '{"config": ' + deep_json() + "}"},
    "deep but parsed": {"texture": TEXTURE[:-1] + ', "authoring": {"a": ' + "[" * 900 + "]" * 900 + "}}",
                        "profile": PROFILE + "description = " + "[" * 200 + "]" * 200 + "\n",
                        "calibration": CALIBRATION + "x = " + "[" * 200 + "]" * 200 + "\n",
                        "effects": EFFECTS[:-1] + ', "x": ' + "[" * 900 + "]" * 900 + "}",
                        "session": '{"config": {"texture": "x", "levels": ' + "[" * 900 + "]" * 900 + "}}"},
    "huge int": {"texture": TEXTURE.replace("20", HUGE, 1), "profile": PROFILE.replace("200", HUGE),
                 "calibration": CALIBRATION.replace("1.3", HUGE), "effects": EFFECTS.replace("1", HUGE, 1),
                 "session": SESSION.replace("}}", f', "trials": {HUGE}}}}}')},
    "large int": {"texture": TEXTURE.replace("20", LARGE, 1), "profile": PROFILE.replace("200", LARGE),
                  "calibration": CALIBRATION.replace("1.3", LARGE), "effects": EFFECTS.replace("1", LARGE, 1),
                  "session": SESSION.replace("}}", f', "trials": {LARGE}}}}}')},
}


@pytest.mark.parametrize("hostile", sorted(HOSTILE))
@pytest.mark.parametrize("loader", sorted(LOADERS))
def test_every_loader_turns_its_parsers_failures_into_one_line(tmp_path, loader, hostile):
    load, error, name, write = LOADERS[loader]
    path = tmp_path / name
    write(path, HOSTILE[hostile][loader])
    with pytest.raises(error) as raised:
        load(path)
    message = str(raised.value)
    assert "\n" not in message and len(message) < 600 and str(path) in message, message
    if hostile == "deep":
        assert "nested too deeply" in message


KEY_PARTS = 60_000  # tomllib's time grows with the square of a key's parts: minutes for this 120 KB


@pytest.mark.parametrize("form", ["a{dots} = 1", "[a{dots}]", "x = {{a{dots} = 1}}", "[[a{dots}]]"])
@pytest.mark.parametrize("loader", ["profile", "calibration"])
def test_a_toml_key_of_thousands_of_parts_is_refused_at_once(tmp_path, loader, form):
    load, error, name, write = LOADERS[loader]
    path = tmp_path / name
    good = {"profile": PROFILE, "calibration": CALIBRATION}[loader]
    write(path, good + form.format(dots=" . a" * KEY_PARTS) + "\n")
    with no_hang(60), pytest.raises(error, match="nested too deeply") as raised:
        load(path)
    assert str(path) in str(raised.value) and len(str(raised.value)) < 300
    write(path, good + 'description_of_dots = "' + "." * 5_000 + " 1.2.3" * 100 + '"\nx = [' + "1.5, " * 1000 + "2]\n")
    try:  # dots in strings and numbers are no key's
        load(path)
    except error as other:
        assert "nested" not in str(other) and "not a valid TOML" not in str(other), other


@pytest.mark.parametrize("loader", sorted(LOADERS))
def test_the_good_files_load(tmp_path, loader):
    """The hostile cases above are these files with one value changed: they load."""
    load, _, name, write = LOADERS[loader]
    path = tmp_path / name
    write(path, {"texture": TEXTURE, "profile": PROFILE, "calibration": CALIBRATION, "effects": EFFECTS,
                 "session": SESSION}[loader])
    assert load(path) is not None


CSV_LOADERS = {  # load, its error type, the file's name, a good header and rows
    "trajectory": (read_touch_log, RenderError, "log.csv", "t_s,x_mm,y_mm", ["0,1,5", "1,2,5"]),
    "measurements": (read_measurements, ModelError, "m.csv", "amplitude_um_pp,relative_friction", ["0,1", "2,0.5"]),
    "table model": (lambda path: load_model(f"table:{path}"), ModelError, "m.csv", "amplitude_um_pp,relative_friction",
                    ["0,1", "1,0.8", "2,0.5"]),
    "finger's force script": (ForceScript.read_csv, DeviceError, "f.csv", "t_s,force_n", ["0,0.5", "1,0.6"]),
    "trial log": (lambda path: read_trials(path.parent), UsageError, "trials.csv", "trial,level,response,correct",
                  ["1,0.5,1,1", "2,0.5,0,0"]),
}


@pytest.mark.parametrize("hostile", ["carriage returns only", "a cell of 200 000 characters"])
@pytest.mark.parametrize("loader", sorted(CSV_LOADERS))
def test_every_csv_loader_turns_the_csv_modules_failures_into_one_line(tmp_path, loader, hostile):
    """What Python's csv module raises (csv.Error: a carriage return inside a line, a field over its limit) is a
    line of the loader's own error, naming the file."""
    load, error, name, header, rows = CSV_LOADERS[loader]
    path = tmp_path / name
    if hostile == "carriage returns only":
        path.write_bytes("\r".join([header, *rows]).encode() + b"\r")
    else:
        path.write_text("\n".join([header + ",note", *(row + ",x" for row in rows)]) + "\n" + rows[-1] + ","
                        + "x" * 200_000 + "\n")
    try:  # read (universal newlines; a note column that is not used) or refused in one line, never csv.Error
        load(path)
    except error as raised:
        message = str(raised)
        assert isinstance(raised, UltraglideError), repr(raised)
        assert "\n" not in message and len(message) < 600 and str(path) in message, message
    assert path.stat().st_size > 0  # refused, never emptied (a trial log is cut at its last newline)
    path.write_text("\n".join([header, *rows]) + "\n")
    assert load(path) is not None  # the same rows, line ends of \n: they load


# ---- a file's text quoted in a refusal: printable, whatever the file holds ------------------------------------
EVIL = "\x1b]0;owned\x07\x1b[2J\u202eevil\r\nnext"  # retitle, clear, read backwards, a line of its own
EVIL_JSON = json.dumps(EVIL)[1:-1]  # also a TOML basic string's escapes
QUOTED = {  # loader: files whose refusal quotes a key, a value or a column the file holds
    "texture": [TEXTURE[:-1] + f', "kind": "{EVIL_JSON}"}}', TEXTURE[:-1] + f', "outside": "{EVIL_JSON}"}}',
                TEXTURE[:-1] + f', "name": "{EVIL_JSON}", "width_mm": "{EVIL_JSON}"}}'],
    "profile": [PROFILE + f'"{EVIL_JSON}" = 1\n', PROFILE.replace("q = 200", f'q = "{EVIL_JSON}"'),
                PROFILE.replace("q = 200", "q = 2") + f'name = "{EVIL_JSON}"\n'],
    "calibration": [CALIBRATION + f'"{EVIL_JSON}" = 1\n', CALIBRATION.replace('"exponential"', f'"{EVIL_JSON}"'),
                    CALIBRATION.replace("tau_um_zp", f'"{EVIL_JSON}"')],
    "effects": ['{"effects_version": 1, "bindings": [{"trigger": {"on": "start"}, "effect": 0.5, '
                f'"{EVIL_JSON}": 1}}]}}', '{"effects_version": 1, "bindings": [{"trigger": {"on": "start"}, '
                f'"effect": {{"type": "{EVIL_JSON}"}}}}]}}',
                f'{{"effects_version": 1, "bindings": [], "{EVIL_JSON}": 1}}',
                f'{{"effects_version": 1, "bindings": [{{"trigger": {{"on": "{EVIL_JSON}"}}, "effect": 0.5}}]}}'],
    "session": [SESSION.replace("}}", f', "method": "{EVIL_JSON}"}}}}'),
                SESSION.replace("}}", f', "participant": "{EVIL_JSON}"}}}}'),
                SESSION.replace("}}", f', "trials": "{EVIL_JSON}"}}}}'),
                SESSION.replace('"grating-1mm"', f'"{EVIL_JSON}"').replace("}}", ', "trials": -4}}')],
}


@pytest.mark.parametrize("loader", sorted(QUOTED))
def test_a_files_text_in_a_refusal_is_quoted_with_its_escapes(tmp_path, loader):
    """An API user's log or terminal gets the refusal as the loader raised it (the command line escapes what it
    prints, a library does not): a key, a value or a name from the file appears there printable, quoted with its
    escapes, on one line."""
    load, error, name, write = LOADERS[loader]
    for number, text in enumerate(QUOTED[loader]):
        path = tmp_path / str(number) / name
        path.parent.mkdir()
        write(path, text)
        with pytest.raises(error) as raised:
            load(path)
        message = str(raised.value)
        assert message.isprintable() and str(path) in message, message


@pytest.mark.parametrize("loader", sorted(CSV_LOADERS))
def test_a_csv_files_column_names_and_cells_in_a_refusal_are_quoted_with_their_escapes(tmp_path, loader):
    load, error, name, header, rows = CSV_LOADERS[loader]
    path = tmp_path / name
    column = EVIL.replace("\r\n", "\x85")  # one CSV line
    bad_cell = rows[-1].split(",")
    bad_cell[1] = column
    for text in (f"{header},{column},{column}\n" + "".join(row + ",1,1\n" for row in rows),
                 f"{column},{header}\n" + "".join(row + ",1\n" for row in rows), f"{column}\n{rows[0]}\n",
                 "\n".join([header, *rows[:-1], ",".join(bad_cell)]) + "\n"):
        path.write_text(text)
        try:
            load(path)
        except error as raised:
            assert str(raised).isprintable() and str(path) in str(raised), str(raised)


@pytest.mark.parametrize("width", ["5e-324", "1e-300", "0.009", "1e-30"])
def test_no_size_makes_a_later_stage_divide_by_zero(tmp_path, width):
    path = texture_png(tmp_path / "tiny.png", f'{{"format_version": 1, "width_mm": {width}, "height_mm": 10}}')
    with pytest.raises(TextureError, match="width_mm must be from 0.01 to 10000"):
        load_texture(path)
    smallest = texture_png(tmp_path / "small.png", '{"format_version": 1, "width_mm": 0.01, "height_mm": 0.01}',
                           size=(2000, 2000))
    texture = load_texture(smallest)  # 2000 pixels over 10 µm: held as one pixel, sampled anywhere
    assert texture.values.shape == (1, 1)
    ratios = Sampler(texture).ratio(np.array([0.0, 5e-3, 1e6]), np.array([0.0, 5e-3, -1e6]), step_mm=0.1)
    assert np.all(np.isfinite(ratios))


# ---- memory: a texture is held at what a finger resolves -----------------------------------------------------
@pytest.fixture(scope="module")
def big_png(tmp_path_factory):
    """99 million pixels (the documented limit is 100 million) in a PNG of a few hundred KB."""
    path = tmp_path_factory.mktemp("big") / "big.png"
    side = 9950
    column = (np.arange(side) % 20 < 10).astype(np.uint8) * 255  # a 1 mm grating at 124 px/mm: 10 px on, 10 off
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", json.dumps({"format_version": 1, "width_mm": 80.0, "height_mm": 80.0}))
    Image.fromarray(np.broadcast_to(column, (side, side)).copy()).save(path, pnginfo=info)
    assert path.stat().st_size < 2_000_000
    return path


def test_a_fine_texture_is_held_at_twenty_pixels_a_millimetre(big_png):
    texture = load_texture(big_png)
    assert (texture.cols, texture.rows) == (1600, 1600) and MAX_PX_PER_MM == 20
    assert texture.authoring["held_from_pixels"] == [9950, 9950]
    # the exact box filter keeps the 1.61 mm grating (20 file pixels of 80/9950 mm): mean 0.5, swinging 0..1
    profile = texture.values[0]
    assert profile.mean() == pytest.approx(0.5, abs=0.01) and profile.min() < 0.05 and profile.max() > 0.95


def test_peak_memory_of_a_command_on_a_99_megapixel_png_is_bounded(big_png, tmp_path):
    """Before: 5.9 GB for `texture info`, 1.5 GB for `export` (issue 26). The bound here is generous (the
    decoded 8-bit image is 99 MB, the held texture 10 MB); the figures are in the README."""
    # the peak of this process's own memory (VmHWM): not ru_maxrss, which Linux carries over an exec from the
    # process that forked it (the test worker, itself over 1 GB late in a whole run)
    script = ("import re, sys; from ultraglide.apps.cli.main import main; status = main(sys.argv[1:]); "
              "status_text = open('/proc/self/status').read(); "
              "print(re.search(r'VmHWM:\\s+(\\d+) kB', status_text).group(1), file=sys.stderr); sys.exit(status)")
    for args in (["texture", "info", str(big_png)],
                 ["export", str(big_png), "-o", str(tmp_path / "a.wav"), "--duration-s", "0.2"]):
        result = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, cwd=ROOT,
                                timeout=600)
        assert result.returncode == 0, result.stderr
        peak_kb = int(result.stderr.strip().splitlines()[-1])
        assert peak_kb < 900_000, f"{args[0]}: {peak_kb / 1000:.0f} MB"
        assert "DecompressionBomb" not in result.stderr and "decompression bomb" not in result.stderr.lower()


def test_colour_and_text_bombs_are_named_from_the_header(tmp_path):
    """A colour texture file is refused by its header, before its pixels are decoded (a 99 M-pixel RGB PNG took
    0.5 GB to be refused); a text chunk that inflates past Pillow's limit is said to be that, not damage."""
    colour = texture_png(tmp_path / "colour.png", TEXTURE, mode="RGB")
    with pytest.raises(TextureError, match="must be grayscale, this one is RGB") as raised:
        load_texture(colour)
    assert str(colour) in str(raised.value)
    info = PngImagePlugin.PngInfo()
    info.add_itxt("ultraglide", TEXTURE)
    info.add_text("Comment", "A" * 30_000_000, zip=True)  # 30 MB of text in 30 KB
    bomb = tmp_path / "bomb.png"
    Image.new("L", (20, 10)).save(bomb, pnginfo=info)
    for run in (load_texture, lambda path: read_image_luminance(path)):
        with pytest.raises(TextureError, match="decompresses to more than Pillow reads") as raised:
            run(bomb)
        assert "damaged" not in str(raised.value) and str(bomb) in str(raised.value)


def test_pillows_decompression_bomb_warning_is_off_in_every_thread():
    """Our limits speak instead; a filter set inside warnings.catch_warnings would be undone by another thread's.
    In a fresh interpreter (pytest sets its own filters): a 99 M-pixel check, over Pillow's 89 M, prints nothing."""
    code = ("import threading, ultraglide.textures.fileformat\nfrom PIL import Image\n"
            "thread = threading.Thread(target=Image._decompression_bomb_check, args=((10_000, 9_900),))\n"
            "thread.start(); thread.join(); Image._decompression_bomb_check((9_900, 10_000))\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stderr == "", result.stderr


def test_a_physically_large_texture_is_held_in_bounded_pixels(tmp_path):
    path = texture_png(tmp_path / "wide.png", '{"format_version": 1, "width_mm": 900, "height_mm": 900}',
                       size=(6000, 6000))
    texture = load_texture(path)  # 6.7 px/mm, but 36 M pixels: held in 16 M at most
    assert texture.cols * texture.rows <= MAX_HELD_PIXELS and texture.cols == texture.rows


# ---- what people and parsers read ---------------------------------------------------------------------------------
def test_printable_escapes_controls_bidi_and_undecodable_bytes():
    assert printable("a\x1b]0;t\x07b\u202ec\x9bd\udcffe\nf") == "a\\u001b]0;t\\u0007b\\u202ec\\u009bd\\udcffe\\u000af"
    assert printable("µ × ok\tand\n", keep="\n\t") == "µ × ok\tand\n"
    assert json.loads(f'"{printable(chr(0x202e) + chr(27))}"') == "\u202e\x1b"  # still the text, as JSON
    line = one_line("k" * 10_000)
    assert len(line) < 700 and line.endswith("(9,400 more characters)")


def test_strict_json_has_no_nan():
    text = json_text({"a": float("nan"), "b": [float("inf"), np.float32("nan"), 1.5], "c": {"d": -np.inf}})
    assert json.loads(text, parse_constant=refuse) == {"a": None, "b": [None, None, 1.5], "c": {"d": None}}


def refuse(constant):
    raise AssertionError(f"not strict JSON: {constant}")


ESCAPES = "\x1b]0;pwned\x07\x1b[2J\x1b[31m\u202e\u2066\x9b"


def assert_clean(text: str) -> None:
    for character in "\x1b\x07\x9b\u202e\u2066":  # the controls in ESCAPES
        assert character not in text, repr(text)


def test_text_from_a_file_reaches_the_terminal_escaped(tmp_path):
    meta = {"format_version": 1, "width_mm": 20, "height_mm": 10, "name": f"evil{ESCAPES}",
            "description": f"said{ESCAPES}", "source": f"src{ESCAPES}", "authoring": {ESCAPES: ESCAPES}}
    path = texture_png(tmp_path / "evil.png", json.dumps(meta), mode="L")
    text = run_cli("texture", "info", path, check=True)
    assert_clean(text.stdout + text.stderr)
    assert "evil\\x1b]0;pwned\\x07" in text.stdout  # quoted with its escapes, as a refusal quotes it
    broken = {"format_version": 1, "width_mm": 20, "height_mm": 10, "name": "n", "description": "d\nFAKE friction 0",
              "source": "s\r\nFAKE kind gradient", "authoring": {"a\nb": "c\nd"}}
    lines = run_cli("texture", "info", texture_png(tmp_path / "lines.png", json.dumps(broken)), check=True).stdout
    plain = {**broken, "description": "d", "source": "s", "authoring": {"a": "c"}}
    expected = run_cli("texture", "info", texture_png(tmp_path / "plain.png", json.dumps(plain)), check=True).stdout
    # as many lines as the same texture's without line breaks in its text: no line of the file's own
    assert len(lines.splitlines()) == len(expected.splitlines()) and "\nFAKE" not in lines, lines
    data = run_cli("texture", "info", path, "--json", check=True)
    assert_clean(data.stdout)
    assert json.loads(data.stdout, parse_constant=refuse)["name"] == meta["name"]
    named = tmp_path / f"bad{ESCAPES}name.png"  # a file name in an error line
    line = assert_one_line_error(run_cli("export", named, "-o", tmp_path / "x.wav"))
    assert_clean(line)


def test_a_usage_error_quotes_what_it_was_given_escaped_and_short(tmp_path):
    """argparse quotes the arguments it refuses: a name a script took from a folder may hold escapes or be long."""
    for args in (["export", "grating-1mm", "-o", tmp_path / "a.wav", ESCAPES + "z" * 20_000],
                 ["texture", "compose", ESCAPES * 3_000, "grating-1mm"], ["export", "grating-1mm", "--speed-mm-s",
                                                                          ESCAPES + "9" * 20_000]):
        result = run_cli(*args)
        line = assert_one_line_error(result)
        assert result.returncode == 2 and len(line) < 1_000, line
        assert_clean(result.stderr)
    assert not (tmp_path / "a.wav").exists()


def test_a_huge_profile_of_unknown_keys_gets_a_short_line(tmp_path):
    keys = "".join(f"key{number} = 1\n" for number in range(200_000))  # 2.6 MB
    path = tmp_path / "p.toml"
    path.write_text(PROFILE + keys)
    with pytest.raises(DeviceError) as raised:
        load_profile(path)
    message = str(raised.value)
    assert len(message) < 500 and "and 199,995 more" in message
    path.write_text(PROFILE + "".join(f"key{number} = 1\n" for number in range(700_000)))  # 10 MB
    with pytest.raises(DeviceError, match="more than 4 MiB") as raised:
        load_profile(path)
    assert len(str(raised.value)) < 300
    line = assert_one_line_error(run_cli("export", "grating-1mm", "--profile", path, "-o", tmp_path / "a.wav"))
    assert len(line) < 400


def test_messages_say_what_the_file_is(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("not a picture\n")
    for args in (["export", notes, "-o", tmp_path / "a.wav"], ["author", notes, "-o", tmp_path / "t.png"],
                 ["texture", "info", notes]):
        result = run_cli(*args)
        line = assert_one_line_error(result)  # no "plain image" warning before it
        assert "not an image" in line
    big = tmp_path / "big.png"
    Image.new("L", (8000, 6000), 255).save(big)  # 48 M pixels, over author's default 40 M
    line = assert_one_line_error(run_cli("author", big, "-o", tmp_path / "t.png"))
    assert "over the limit of 40,000,000" in line and "--max-pixels" in line and "damaged" not in line
    result = run_cli("export", big, "-o", tmp_path / "a.wav")
    line = result.stderr.strip().splitlines()[-1]
    assert result.returncode == 2 and "over the limit" in line and "damaged" not in line  # an input it cannot use
    assert "`ultraglide author`" in line  # the option belongs to author, and the line says so
    palette = texture_png(tmp_path / "palette.png", TEXTURE, mode="P")
    assert load_texture(palette).values.shape == (10, 20)


def test_an_audio_device_that_is_not_there_is_named_so(tmp_path):
    """With one audio output (ALSA's file PCM as the default card) and with none, ``audio:99`` is no device."""
    from test_devices import ASOUNDRC

    with_card, without = tmp_path / "card", tmp_path / "none"
    with_card.mkdir()
    without.mkdir()
    (with_card / ".asoundrc").write_text(ASOUNDRC.format(path=tmp_path / "capture.raw"))
    (without / ".asoundrc").write_text("pcm.!default { type hw card 99 }\n")
    for home, listed in ((with_card, "outputs: 0 ("), (without, "no audio output")):
        line = assert_one_line_error(run_cli("play", "grating-1mm", "--device", "audio:99", "--profile", "sim-plate",
                                             "--duration-s", "0.2",
                                             env={"HOME": str(home)}))
        assert "no such audio output: 99" in line and listed in line and "carrier" not in line, line


JSON_COMMANDS = {
    "model": ["model", "--force", "0.3", "--ratio", "0.8", "--json"],
    "calibrate": ["calibrate", str(ROOT / "apps" / "data" / "monnoyer2018-fit.csv"), "--json"],
    "textures": ["textures", "--json"],
    "texture info": ["texture", "info", "wood", "--json"],
    "devices": ["devices", "--json"],
    "export": ["export", "grating-1mm", "-o", "{tmp}/a.wav", "--duration-s", "0.2", "--json"],
    "play": ["play", "grating-1mm", "--device", "null", "--duration-s", "0.3", "--json"],
    "play --track-resonance": ["play", "grating-1mm", "--device", "sim", "--duration-s", "0.5", "--track-resonance",
                               "--json"],
    "latency": ["latency", "--device", "null", "--steps", "3", "--json"],
    "plate sweep": ["plate", "sweep", "--device", "sim", "-o", "{tmp}/m.toml", "--steps", "5", "--json"],
    "plate check": ["plate", "check", "--device", "sim", "--rule", "R-VERSION", "--json"],
    "experiment": ["experiment", "threshold", "grating-1mm", "--trials", "4", "--observer", "sim:threshold=0.1",
                   "--out", "{tmp}/s", "--json"],
}


if shutil.which("arm-none-eabi-gcc"):
    JSON_COMMANDS["firmware build"] = ["firmware", "build", "--json"]


@pytest.mark.parametrize("command", sorted(JSON_COMMANDS))
def test_every_json_output_is_strict_json(tmp_path, command):
    args = [arg.format(tmp=tmp_path) for arg in JSON_COMMANDS[command]]
    result = run_cli(*args, check=True, timeout=600)
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    assert lines, result.stderr
    for line in lines:
        json.loads(line, parse_constant=refuse)
    assert_clean(result.stdout)


def test_plate_sim_json_events_are_strict_json(tmp_path):
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate-sim", "--link", str(tmp_path / "plate"),
                                "--json"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = process.stdout.readline()
    finally:
        process.send_signal(signal.SIGTERM)
        process.communicate(timeout=60)
    assert first.strip(), "plate-sim printed no event"
    json.loads(first, parse_constant=refuse)


@pytest.mark.parametrize("misspelt", [
    '{"effects_version": 1, "bindings": [{"trigger": {"on": "start"}, "effect": 0.5, "relase_s": 5}]}',
    '{"effects_version": 1, "bindings": [], "binding": [{"trigger": {"on": "start"}, "effect": 0.5}]}'])
def test_an_effects_file_refuses_a_field_it_does_not_know(tmp_path, misspelt):
    """A misspelt binding field was the default, silently (``relase_s``: the 0.02 s release, not 5 s), as a
    misspelt profile key or calibration parameter never is."""
    path = tmp_path / "e.json"
    path.write_text(misspelt)
    with pytest.raises(TextureError, match="unknown field '(relase_s|binding)'"):
        load_effects(path)
    line = assert_one_line_error(run_cli("play", "grating-1mm", "--effects", path, "--device", "null",
                                         "--duration-s", "0.1"))
    assert "unknown field" in line


SIM_OBSERVER = "sim:threshold=0.1,slope=3"


@pytest.fixture(scope="module")
def finished_session(tmp_path_factory):
    directory = tmp_path_factory.mktemp("session") / "s"
    run_cli("experiment", "threshold", "grating-1mm", "--trials", "5", "--observer", SIM_OBSERVER, "--out", directory,
            "--no-figures", check=True)
    return directory


@pytest.mark.parametrize("config", [{"start_level": 5e-324}, {"start_level": -0.0}, {"start_level": 0.9},
                                    {"level_range": [5e-324, 0.5], "start_level": 0.0},
                                    {"level_range": [0.5, 0.1]}, {"level_range": [0.0, 0.5]}])
def test_levels_a_procedure_cannot_take_are_refused_before_anything_is_written(tmp_path, finished_session, config):
    """A staircase's start outside its levels' range (5e-324, -0 against 0.005..0.6), from a session.json resumed
    or from the command line, was a ValueError from the staircase with its traceback, after the session's folder
    was made."""
    directory = tmp_path / "s"
    shutil.copytree(finished_session, directory)
    session = json.loads((directory / "session.json").read_text())
    session["config"].update(config)
    (directory / "session.json").write_text(json.dumps(session))
    before = {path.name: path.read_bytes() for path in directory.iterdir()}
    line = assert_one_line_error(run_cli("experiment", "threshold", "--resume", directory))
    assert f"{directory / 'session.json'}: " in line and "levels' range" in line, line
    assert {path.name: path.read_bytes() for path in directory.iterdir()} == before
    line = assert_one_line_error(run_cli("experiment", "threshold", "grating-1mm", "--trials", "5", "--observer",
                                         SIM_OBSERVER, "--out", tmp_path / "new", "--start-level", "0.001"))
    assert "the start level 0.001 lies outside the levels' range 0.005..0.6" in line
    assert not (tmp_path / "new").exists()
