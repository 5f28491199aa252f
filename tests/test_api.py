"""The public API: every name in ``ultraglide.__all__`` resolves, lazily, to a documented object of
the package it claims; nothing private is exported; ``import ultraglide`` loads none of the heavy parts;
``export_wav`` writes what the command writes."""

from __future__ import annotations

import ast
import inspect
import subprocess
import sys

import numpy as np
import pytest
import soundfile
from conftest import ROOT, run_cli

import ultraglide


def test_every_public_name_resolves_and_is_documented():
    assert len(ultraglide.__all__) == len(set(ultraglide.__all__))
    for name in ultraglide.__all__:
        value = getattr(ultraglide, name)
        assert not name.startswith("_") or name == "__version__"
        if name == "__version__":
            continue
        assert value.__module__.startswith("ultraglide."), (name, value.__module__)
        assert inspect.getdoc(value), f"ultraglide.{name} has no docstring"
        assert ".apps" not in value.__module__, f"ultraglide.{name} comes from the apps leaf"
    assert set(dir(ultraglide)) >= set(ultraglide.__all__)


def _public_callables():
    for name in ultraglide.__all__:
        value = getattr(ultraglide, name)
        if inspect.isfunction(value):
            yield name, value
        elif inspect.isclass(value) and value.__module__.startswith("ultraglide."):
            for member, function in vars(value).items():
                if inspect.isfunction(function) and not member.startswith("_"):
                    yield f"{name}.{member}", function


def test_public_functions_have_type_hints_and_docstrings():
    missing = []
    for name, function in _public_callables():
        signature = inspect.signature(function)
        unannotated = [p for p, parameter in signature.parameters.items()
                       if p not in ("self", "cls") and parameter.annotation is inspect.Parameter.empty]
        if unannotated or signature.return_annotation is inspect.Signature.empty:
            missing.append(f"{name}: {unannotated or 'return'}")
        if not inspect.getdoc(function):
            missing.append(f"{name}: docstring")
    assert not missing, missing


# the modules whose every public function, class and method has a docstring (the public API and what it is built
# of); the rest of the package is documented module by module as it is touched
DOCUMENTED = ("ultraglide/__init__.py", "ultraglide/api.py", "ultraglide/client.py", "ultraglide/errors.py",
              "ultraglide/lazy.py", "textures", "render", "devices/output", "devices/profiles.py", "devices/errors.py",
              "ultraglide/experiment")


def _documented_paths():
    """The source files of the documented modules."""
    return sorted(path for place in DOCUMENTED
                  for path in ([ROOT / place] if place.endswith(".py") else (ROOT / place).rglob("*.py")))


def _public_definitions(tree):
    """(name, node) of every public module-level function and class of a parsed module, and of their public
    methods and properties."""
    for node in tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) and not node.name.startswith("_"):
            yield node.name, node
            if isinstance(node, ast.ClassDef):
                yield from ((f"{node.name}.{member.name}", member) for member in node.body
                            if isinstance(member, ast.FunctionDef | ast.AsyncFunctionDef)
                            and not member.name.startswith("_"))


def test_the_documented_modules_stay_documented():
    paths = _documented_paths()
    assert len(paths) > 60
    lacking = [f"{path.relative_to(ROOT)}:{node.lineno} {name}" for path in paths
               for name, node in _public_definitions(ast.parse(path.read_text(encoding="utf-8")))
               if ast.get_docstring(node) is None]
    assert not lacking, f"{len(lacking)} public definitions without a docstring: {lacking}"


def _module_of(path):
    """The module name a source file of the repository is imported as (top-level folders live in ultraglide.*)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts if parts[0] == "ultraglide" else ["ultraglide", *parts])


# classes whose example needs more than a doctest should start; each stays named here until it has one (Client and
# AsyncClient have theirs: a service in the doctest's process on a Unix socket, its engine on the null device)
CLASSES_WITHOUT_EXAMPLE: set[str] = set()


def test_the_documented_modules_functions_and_classes_have_running_examples():
    """Every public module-level function and class of the documented modules has an Examples section whose
    ``>>>`` lines doctest finds in the imported module, not all skipped, so tests/test_doctests.py runs them (a
    decorated function doctest cannot see would pass a look at its source alone)."""
    import doctest
    import importlib

    finder = doctest.DocTestFinder()
    lacking, checked = [], 0
    for path in _documented_paths():
        names = [name for name, node in _public_definitions(ast.parse(path.read_text(encoding="utf-8")))
                 if "." not in name]
        if not names:
            continue
        module = importlib.import_module(_module_of(path))
        found = {test.name for test in finder.find(module)  # one example at least that runs (not skipped)
                 if any(not example.options.get(doctest.SKIP) for example in test.examples)}
        for name in names:
            checked += 1
            doc = inspect.getdoc(getattr(module, name)) or ""
            if f"{module.__name__}.{name}" not in found or "Examples" not in _sections(doc):
                lacking.append(f"{path.relative_to(ROOT)}: {name}")
    assert checked > 300
    assert set(lacking) == CLASSES_WITHOUT_EXAMPLE, (
        f"without a running example: {sorted(set(lacking) - CLASSES_WITHOUT_EXAMPLE)}; "
        f"with one now (strike from CLASSES_WITHOUT_EXAMPLE): {sorted(CLASSES_WITHOUT_EXAMPLE - set(lacking))}")


# modules of the documented set whose public methods are documented in words, not yet by running examples (every
# other documented module's public methods and properties have theirs); strike one once its methods all have
METHODS_WITHOUT_EXAMPLES: set[str] = set()


def test_the_documented_modules_methods_have_running_examples():
    """Every public method and property of the documented modules' public classes (but those of
    :data:`METHODS_WITHOUT_EXAMPLES`) has an Examples section whose ``>>>`` lines doctest finds in the imported
    module, not all skipped."""
    import doctest
    import importlib

    finder = doctest.DocTestFinder()
    lacking, checked, exempt = [], 0, set()
    for path in _documented_paths():
        names = [name for name, node in _public_definitions(ast.parse(path.read_text(encoding="utf-8")))
                 if "." in name]
        if not names:
            continue
        if str(path.relative_to(ROOT)) in METHODS_WITHOUT_EXAMPLES:
            exempt.add(str(path.relative_to(ROOT)))
            continue
        module = importlib.import_module(_module_of(path))
        found = {test.name for test in finder.find(module)
                 if any(not example.options.get(doctest.SKIP) for example in test.examples)}
        for name in names:
            checked += 1
            owner, member = name.split(".")
            doc = inspect.getdoc(inspect.getattr_static(getattr(module, owner), member)) or ""
            if f"{module.__name__}.{name}" not in found or "Examples" not in _sections(doc):
                lacking.append(f"{path.relative_to(ROOT)}: {name}")
    assert checked > 250
    assert exempt == METHODS_WITHOUT_EXAMPLES, f"no longer in the documented set: {METHODS_WITHOUT_EXAMPLES - exempt}"
    assert not lacking, f"{len(lacking)} public methods without a running example: {lacking}"


def test_unknown_names_raise_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'kernels'"):
        ultraglide.kernels  # noqa: B018 - internal modules are not re-exported
    assert not hasattr(ultraglide, "apps_cli")


def test_import_is_lazy():
    code = ("import sys, ultraglide; heavy = [m for m in ('numpy', 'scipy', 'numba', 'matplotlib', "
            "'ultraglide.render.renderer', 'ultraglide.apps.cli.main') if m in sys.modules]; print(heavy); "
            "ultraglide.grating; print('numpy' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[:2] == ["[]", "True"]


@pytest.mark.slow
def test_export_wav_matches_the_export_command(tmp_path):
    library = ultraglide.export_wav("grating-2mm", tmp_path / "lib.wav", duration_s=0.5, speed_mm_s=80.0)
    run_cli("export", "grating-2mm", "-o", tmp_path / "cli.wav", "--duration-s", "0.5", "--speed-mm-s", "80",
            check=True)
    ours, rate = soundfile.read(tmp_path / "lib.wav", dtype="float32")
    theirs, _ = soundfile.read(tmp_path / "cli.wav", dtype="float32")
    assert rate == library.rate_hz == 96000
    assert library.duration_s == pytest.approx(len(ours) / rate)
    np.testing.assert_array_equal(ours, theirs)  # one path from renderer to samples
    assert np.max(np.abs(ours)) > 0.2


def test_export_wav_refuses_bad_input_and_leaves_nothing(tmp_path):
    with pytest.raises(ultraglide.RenderError, match="int16, or|float32, int24, int16"):
        ultraglide.export_wav("grating-2mm", tmp_path / "x.wav", format="int8", duration_s=0.1)
    with pytest.raises(ultraglide.RenderError, match=r"\.wav"):
        ultraglide.export_wav("grating-2mm", tmp_path / "x.mp3", duration_s=0.1)
    with pytest.raises(ultraglide.TextureError, match="no texture"):
        ultraglide.export_wav("no-such-texture", tmp_path / "x.wav", duration_s=0.1)
    assert list(tmp_path.iterdir()) == []


# ---- names and arrays everywhere; one call renders a swipe ---------------------------------------------------

def _profile_file(name: str = "sim-plate") -> dict:
    """The bundled profile as the TOML file says it, read here by tomllib (not by the package's loader)."""
    import tomllib

    from conftest import ROOT

    return tomllib.loads((ROOT / "devices" / "profiles" / f"{name}.toml").read_text(encoding="utf-8"))


def _peak_hz(signal: np.ndarray, rate_hz: float) -> float:
    """The strongest frequency in ``signal`` (Hz), from its spectrum (Hann window, the mean removed), refined by
    a parabola through the peak bin and its neighbours."""
    windowed = (signal - np.mean(signal)) * np.hanning(len(signal))
    spectrum = np.abs(np.fft.rfft(windowed))
    k = int(np.argmax(spectrum[1:-1])) + 1
    a, b, c = np.log(spectrum[k - 1:k + 2] + 1e-30)
    return (k + 0.5 * (a - c) / (a - 2 * b + c)) * rate_hz / len(signal)


def test_the_renderer_takes_names():
    plate = _profile_file()
    renderer = ultraglide.Renderer("grating-1mm", "stretched", "sim-plate", trajectory=ultraglide.SwipePath())
    assert renderer.carrier_hz == plate["resonance_hz"]
    assert renderer.limit_um_pp == plate["max_amplitude_um_pp"]
    assert type(renderer.model).__name__ == "StretchedExponentialModel"
    assert isinstance(renderer, ultraglide.render.renderer.Renderer)  # the render layer's, named
    renderer.set_model("exponential")
    assert type(renderer.model).__name__ == "ExponentialModel"
    with pytest.raises(ultraglide.DeviceError, match="no plate profile"):
        ultraglide.Renderer("grating-1mm", "stretched", "no-such-plate")
    with pytest.raises(ultraglide.ModelError, match="unknown model"):
        ultraglide.Renderer("grating-1mm", "no-such-model")
    with pytest.raises(ultraglide.UltraglideError, match="a model is a FrictionModel or a model's name"):
        ultraglide.Renderer("grating-1mm", 3)
    with pytest.raises(ultraglide.UltraglideError, match="a plate profile is a PlateProfile"):
        ultraglide.Renderer("grating-1mm", "stretched", 25000.0)


def test_control_takes_a_duration_at_the_documented_rate():
    renderer = ultraglide.Renderer("grating-1mm", trajectory=ultraglide.SwipePath(duration_s=1.0))
    assert renderer.control_rate_hz == 12000.0
    block = renderer.control(duration_s=0.25)
    assert len(block.drive_um_pp) == 3000
    assert block.time_s[1] - block.time_s[0] == pytest.approx(1 / 12000)
    for bad in ({}, {"n": 10, "duration_s": 0.1}, {"duration_s": -1.0}, {"duration_s": float("nan")}):
        with pytest.raises(ultraglide.RenderError, match="duration_s|n \\(control samples\\)"):
            renderer.control(**bad)


def test_a_swipe_path_starts_where_across_would_on_the_texture_rendered():
    swipe = ultraglide.render_swipe("grating-1mm", ultraglide.SwipePath(speed_mm_s=50.0, duration_s=0.2))
    texture = ultraglide.resolve_texture("grating-1mm")
    touching = swipe.touching
    # a straight swipe lands at a tenth of the width, half-way down, and moves at its speed
    assert swipe.x_mm[0] == pytest.approx(0.1 * texture.width_mm)
    assert np.all(swipe.y_mm[touching] == pytest.approx(texture.height_mm / 2))
    t = swipe.time_s[touching]
    np.testing.assert_allclose(swipe.x_mm[touching], 0.1 * texture.width_mm + 50.0 * t, atol=1e-9)
    assert t[-1] == pytest.approx(0.2, abs=2 / 12000)
    with pytest.raises(ultraglide.RenderError, match="no start"):
        ultraglide.SwipePath().state([0.0])


def test_render_swipe_puts_the_envelope_on_the_plates_resonance():
    plate = _profile_file()
    swipe = ultraglide.render_swipe("grating-1mm", duration_s=0.5, speed_mm_s=100.0)
    assert swipe.rate_hz == 96000 and swipe.audio.dtype == np.float32
    # the carrier, from the audio's own spectrum, is the resonance the profile file declares
    steady = swipe.audio[9600:9600 + 32768]
    assert _peak_hz(steady, swipe.rate_hz) == pytest.approx(plate["resonance_hz"], abs=2.0)
    # a 1 mm grating swiped at 100 mm/s is felt at 100 Hz: the envelope's strongest modulation
    touching = swipe.envelope_um_pp[(swipe.time_s > 0.05) & swipe.touching]
    assert _peak_hz(touching, swipe.control_rate_hz) == pytest.approx(100.0, rel=0.03)
    # the limits of the file hold for the arrays
    assert swipe.limit_um_pp == plate["max_amplitude_um_pp"]
    assert swipe.target_um_pp.max() <= plate["max_amplitude_um_pp"] + 1e-9
    assert swipe.envelope_um_pp.max() <= plate["max_amplitude_um_pp"] + 1e-9
    assert swipe.drive_um_pp.max() <= plate["max_drive_um_pp"] + 1e-9 and swipe.drive_um_pp.min() >= 0
    # the audio's amplitude, demodulated at the carrier millisecond by millisecond (25 carrier periods), is the
    # limited drive over the profile's full scale: the audio one control period behind the drive, linear between
    # control samples (8 audio frames each)
    t = np.arange(len(swipe.audio)) / swipe.rate_hz
    baseband = swipe.audio * np.exp(-2j * np.pi * plate["resonance_hz"] * t)
    ms = len(swipe.audio) // 96
    amplitude_um_pp = 2 * np.abs(baseband[: ms * 96].reshape(ms, 96).mean(axis=1)) * plate["full_scale_um_pp"]
    knots = np.concatenate([[0.0], swipe.drive_um_pp])
    linear = np.interp(np.arange(ms * 96) / 8.0, np.arange(len(knots)), knots)
    drive = linear.reshape(ms, 96).mean(axis=1)
    np.testing.assert_allclose(amplitude_um_pp[20:450], drive[20:450], atol=0.03 * plate["full_scale_um_pp"])
    assert drive[20:450].max() > 2.0  # something to measure


def test_render_swipe_lasts_the_path_then_the_rest_and_gives_what_export_writes(tmp_path):
    swipe = ultraglide.render_swipe("dots", duration_s=0.3)
    result = ultraglide.export_wav("dots", tmp_path / "dots.wav", duration_s=0.3)
    samples, rate = soundfile.read(tmp_path / "dots.wav", dtype="float32")
    assert rate == swipe.rate_hz
    np.testing.assert_array_equal(swipe.audio, samples)  # one path from the renderer to the samples
    assert swipe.duration_s == pytest.approx(result.duration_s)
    assert 0.3 < swipe.duration_s < 0.4  # the path, then the output coming to rest
    assert len(swipe.time_s) == len(swipe.drive_um_pp) == len(swipe.ratio) >= len(swipe.audio) // 8
    assert abs(swipe.audio[-96:]).max() < 1e-4  # at rest at the end
    with pytest.raises(ultraglide.RenderError, match="brings its own duration"):
        ultraglide.render_swipe("dots", ultraglide.SwipePath(), duration_s=1.0)


def test_render_swipe_gives_the_ratio_its_amplitudes_were_asked_for():
    """Under the default model the renderer plans: the amplitude is the static law's for the planned ratio (read
    back through the stretched model's own inverse), and the planned ratio is not the texture's; under
    ``stretched`` it is the texture's."""
    stretched = ultraglide.load_model("stretched")
    planned = ultraglide.render_swipe("grating-1mm", duration_s=0.3)
    inside = planned.touching & (planned.planned_ratio < 1.0)
    assert inside.sum() > 1000
    expected = stretched.amplitude_um_pp(planned.planned_ratio[inside], 0.5, planned.limit_um_pp).amplitude_um_pp
    np.testing.assert_allclose(planned.target_um_pp[inside], expected, rtol=1e-6, atol=1e-9)
    assert np.abs(planned.planned_ratio - planned.ratio)[planned.touching].max() > 0.2
    static = ultraglide.render_swipe("grating-1mm", duration_s=0.3, model="stretched")
    np.testing.assert_array_equal(static.planned_ratio, static.ratio)


def test_an_array_with_a_size_is_a_texture_everywhere(tmp_path):
    # bars 2 mm wide (a 4 mm period) over 80 mm: swiped at 100 mm/s, felt at 25 Hz
    bars = np.tile(np.repeat([0.2, 1.0], 2), (10, 20))  # 80 columns, 1 mm each
    swipe = ultraglide.render_swipe(bars, width_mm=80.0, duration_s=0.6)
    touching = swipe.envelope_um_pp[(swipe.time_s > 0.05) & (swipe.time_s < 0.45)]  # planned far from the lift
    assert swipe.touching[(swipe.time_s > 0.05) & (swipe.time_s < 0.45)].all()
    period = round(0.04 * swipe.control_rate_hz)  # the envelope repeats every 40 ms, and not every 20 ms
    same = np.sqrt(np.mean((touching[period:] - touching[:-period]) ** 2))
    half = np.sqrt(np.mean((touching[period // 2:] - touching[:-(period // 2)]) ** 2))
    assert same < 0.05 * half
    # the ratio under the finger is the array's, each value at its pixel's centre and linear between them
    expected = np.interp(swipe.x_mm[swipe.touching], [0.5, 1.5, 2.5, 3.5], [0.2, 0.2, 1.0, 1.0], period=4.0)
    np.testing.assert_allclose(swipe.ratio[swipe.touching], expected, atol=0.02)
    renderer = ultraglide.Renderer(bars, width_mm=80.0, height_mm=5.0)
    assert (renderer.texture.width_mm, renderer.texture.height_mm) == (80.0, 5.0)
    assert ultraglide.Renderer(bars, width_mm=80.0).texture.height_mm == 10.0  # square pixels
    result = ultraglide.export_wav(bars, tmp_path / "bars.wav", width_mm=80.0, duration_s=0.2)
    assert soundfile.info(result.path).frames > 0


@pytest.mark.parametrize(("texture", "options", "message"), [
    (np.ones((4, 4)), {}, "needs its physical size: give width_mm="),
    (np.ones(4), {"width_mm": 10.0}, "is 2-D"),
    (np.full((4, 4), 2.0), {"width_mm": 10.0}, "within 0..1"),
    (np.array([["a", "b"]]), {"width_mm": 10.0}, "holds friction ratios"),
    (np.ones((4, 4)), {"width_mm": "wide"}, "sizes in mm"),
    (42, {}, "a texture is a Texture, a library name"),
    ([[0.5, 0.5]], {}, "a texture is a Texture"),
    ("grating-1mm", {"width_mm": 10.0}, "this texture has its own size"),
])
def test_a_texture_that_is_not_one_says_what_to_give(tmp_path, texture, options, message):
    for call in (lambda: ultraglide.render_swipe(texture, duration_s=0.1, **options),
                 lambda: ultraglide.export_wav(texture, tmp_path / "x.wav", duration_s=0.1, **options),
                 lambda: ultraglide.Renderer(texture, **options)):
        with pytest.raises(ultraglide.UltraglideError, match=message) as caught:
            call()
        assert "\n" not in str(caught.value)
    assert list(tmp_path.iterdir()) == []


# classes whose docstrings are numpy-style whole: the sections each must have besides an Example (Parameters for
# what the constructor takes, Attributes for what is read off an object made elsewhere; an error says what it is
# and shows where it comes from); the rest say what they are in words, and their methods are documented one by one
NUMPY_CLASSES = {
    "Renderer": {"Parameters"}, "SwipePath": {"Parameters"}, "Rendered": {"Attributes"},
    "Texture": {"Parameters", "Raises"}, "PlateProfile": {"Parameters", "Raises"},
    "FrictionModel": {"Attributes"}, "PaperModel": {"Parameters"}, "ExponentialModel": {"Parameters", "Raises"},
    "StretchedExponentialModel": {"Parameters", "Raises"}, "TableModel": {"Parameters", "Raises"},
    "SqueezeFilmModel": {"Parameters"}, "FilmParams": {"Parameters", "Raises"},
    "Engine": {"Attributes", "Raises"}, "OutputStage": {"Parameters", "Raises"},
    "UltraglideError": set(), "DeviceError": set(), "TextureError": set(), "ModelError": set(),
    "RenderError": set(), "EngineError": set(), "FitError": set(), "ForceRangeWarning": set(),
    "AuthoringOptions": {"Parameters", "Raises"}, "Sampler": {"Parameters"}, "RenderSettings": {"Parameters", "Raises"},
    "RecordedTrajectory": {"Parameters", "Raises"}, "EngineConfig": {"Parameters"}, "EngineStatus": {"Attributes"},
    "BlockSource": {"Attributes"}, "Device": {"Attributes"}, "ExportResult": {"Attributes"},
    "EnvelopeSource": {"Parameters"}, "ProtocolError": set(),
}


def _sections(doc: str) -> set[str]:
    """The numpy-style section headings of a docstring (a title underlined with dashes)."""
    lines = doc.splitlines()
    return {lines[i].strip() for i in range(len(lines) - 1)
            if lines[i].strip() and set(lines[i + 1].strip()) == {"-"} and len(lines[i + 1].strip()) >= 3}


def test_the_public_functions_and_classes_have_numpy_docstrings():
    import doctest

    assert set(NUMPY_CLASSES) <= set(ultraglide.__all__)
    lacking = []
    for name in ultraglide.__all__:
        value = getattr(ultraglide, name)
        if inspect.isfunction(value):
            wanted = {"Returns", "Examples"} | ({"Parameters"} if inspect.signature(value).parameters else set())
        elif name in NUMPY_CLASSES:
            wanted = {"Examples"} | NUMPY_CLASSES[name]
        else:
            continue
        doc = inspect.getdoc(value)
        missing = wanted - _sections(doc)
        if missing:
            lacking.append(f"{name}: {sorted(missing)}")
        elif "Examples" in wanted and not doctest.DocTestParser().get_examples(doc):
            lacking.append(f"{name}: an Examples section without a >>> line")
    assert not lacking, lacking


# numpydoc's section names: a docstring's headings are these, spelled so (``Examples``, never ``Example``), in modules,
# classes, functions and methods alike, so documentation tools and readers find them
NUMPY_SECTIONS = {"Parameters", "Other Parameters", "Returns", "Yields", "Receives", "Raises", "Warns", "Warnings",
                  "See Also", "Notes", "References", "Examples", "Attributes", "Methods"}
SOURCE_FOLDERS = ("ultraglide", "textures", "render", "devices", "apps")


def test_every_docstring_heads_its_sections_with_numpys_names():
    """Module docstrings included: a heading (a title underlined with dashes) that numpydoc does not know, such as
    a singular ``Example``, fails."""
    wrong, modules = [], 0
    for folder in SOURCE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"))
            modules += 1
            for node in [tree, *(node for node in ast.walk(tree)
                                 if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef))]:
                doc = ast.get_docstring(node)
                for heading in sorted(_sections(doc or "") - NUMPY_SECTIONS):
                    wrong.append(f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 1)} {heading!r}")
                if _doctest_in_a_literal_block(doc or ""):
                    wrong.append(f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 1)} a >>> example under "
                                 "'Example::' (an rST literal block), not an Examples section")
    assert modules > 200
    assert not wrong, f"{len(wrong)} docstring headings numpydoc does not know: {wrong}"


def _doctest_in_a_literal_block(doc: str) -> bool:
    """Whether a ``>>>`` line sits in an rST literal block under a bare ``Example::`` or ``Examples::``: a heading in
    disguise, which doctest runs but numpydoc and readers of the sections do not see. Such a block of plain code (a
    sketch that needs hardware), or a sentence ending ``::`` that introduces an example, is fine."""
    lines = doc.split("\n")
    for k, line in enumerate(lines):
        if line.strip() in ("Example::", "Examples::"):
            indent = len(line) - len(line.lstrip())
            for inner in lines[k + 1:]:
                if inner.strip() and len(inner) - len(inner.lstrip()) <= indent:
                    break
                if inner.strip().startswith(">>>"):
                    return True
    return False
