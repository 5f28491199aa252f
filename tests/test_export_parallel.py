"""``ultraglide export`` on several threads: seamless chunks, a progress bar only on terminals, a light --help."""

import fcntl
import os
import select
import struct
import subprocess
import sys
import termios
import time

import numpy as np
import pytest
import soundfile
from conftest import ROOT, assert_one_line_error, run_cli, start_cli
from ultraglide.apps.cli.parser import build_parser
from ultraglide.apps.commands.render_setup import load_inputs, make_renderer
from ultraglide.devices.output.carrier import Carrier
from ultraglide.devices.output.stage import Modulation
from ultraglide.render.engine.sources import offline_stage
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture

from ultraglide.api import BLOCK_S, write_wav

RATE = 96000
CARRIER_HZ = 25000.0


def references(argv: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """What ``export argv`` should write, made here by the library on this thread: as a device pulls it,
    block by block (one carrier call a block), and as one carrier call over the whole span."""
    args = build_parser().parse_args(["export", *argv])
    inputs = load_inputs(args)
    renderer = make_renderer(inputs, args, args.rate)
    total = int(round((inputs.trajectory.end_s - inputs.trajectory.start_s + renderer.tail_s) * args.rate))
    stage = offline_stage(renderer)
    drives = []  # the limited envelope, block by block
    stage.observers.append(drives.append)
    block = int(BLOCK_S * args.rate)
    pulled = np.concatenate([stage.pull(min(block, total - done), None) for done in range(0, total, block)])
    table, offset = Carrier(renderer.carrier_hz, args.rate).span(total)
    whole = np.empty(total, dtype=np.float32)
    Modulation(np.concatenate([[0.0], *drives]), 0, stage.upsampling, 1.0 / renderer.profile.full_scale_um_pp,
               table, offset, total).render(whole)
    return pulled, whole


@pytest.mark.parametrize("threads", ["1", "7"])
def test_parallel_export_equals_a_single_chunk_render_sample_for_sample(tmp_path, threads):
    # 7 chunks a block: boundaries fall inside control periods (not multiples of 8 frames) and
    # anywhere in the carrier's 96-frame period; 2.3 s spans blocks and a last, shorter block
    out = tmp_path / "zigzag.wav"
    argv = ["grating-1mm", "--path", "zigzag", "--duration-s", "2.3", "-o", str(out)]
    run_cli("export", *argv, "--threads", threads, check=True)
    written, rate = soundfile.read(out, dtype="float32")
    assert rate == RATE
    pulled, whole = references(argv)
    assert len(written) == len(pulled) == len(whole)
    assert np.array_equal(written, whole)
    assert np.array_equal(written, pulled)
    assert np.max(np.abs(whole)) > 0.1  # a real signal, not silence on both sides


def test_a_touch_log_export_equals_a_single_chunk_render(tmp_path):
    # a recorded path at 192 kHz (16 frames a control sample), in 3 chunks a block
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(1 / 240, 1 / 60, 400))  # 60-240 Hz, about 3 s
    x = 10 + 60 * (t - t[0]) + 3 * np.sin(7 * t)
    y = 25 + 10 * np.sin(2 * t)
    log = tmp_path / "touch.csv"
    log.write_text("t_s,x_mm,y_mm,force_n\n" + "".join(f"{a:.6f},{b:.4f},{c:.4f},0.4\n" for a, b, c in zip(t, x, y,
                                                                                                           strict=True)))
    out = tmp_path / "log.wav"
    argv = ["checkerboard-5mm", "--trajectory", str(log), "-o", str(out), "--rate", "192000"]
    run_cli("export", *argv, "--threads", "3", check=True)
    written, rate = soundfile.read(out, dtype="float32")
    assert rate == 192000
    pulled, whole = references(argv)
    assert np.array_equal(written, pulled) and np.array_equal(written, whole)
    assert np.max(np.abs(whole)) > 0.1


@pytest.fixture(scope="module")
def uniform_texture(tmp_path_factory):
    """Friction 0.7 everywhere: a steady amplitude whatever the finger does."""
    path = tmp_path_factory.mktemp("textures") / "uniform.png"
    save_texture(Texture(np.full((40, 64), 0.7, dtype=np.float32), 80.0, 50.0, name="uniform"), path)
    return path


def test_carrier_phase_is_continuous_across_chunk_boundaries(tmp_path, uniform_texture):
    out = tmp_path / "steady.wav"
    run_cli("export", uniform_texture, "--path", "zigzag", "--duration-s", "3", "-o", out, "--threads", "7",
            check=True)
    samples, rate = soundfile.read(out, dtype="float64")
    # steady part: from 0.5 s (ramps and smoothing settled) to 2.9 s (before the finger lifts); it
    # crosses 2 block joins and 14 chunk joins (every 96000 / 7 frames: not whole carrier periods of 96 frames)
    n = np.arange(rate // 2, int(2.9 * rate))
    steady = samples[n]
    ideal = np.sin(2 * np.pi * CARRIER_HZ * n / rate)  # the carrier's phase from the absolute index alone
    amplitude = float(steady @ ideal / (ideal @ ideal))
    assert 0.05 < amplitude <= 1.0
    assert np.max(np.abs(steady - amplitude * ideal)) < 1e-6  # float32 rounding; a phase slip would be ~0.1

    segment = samples[rate // 2: rate // 2 + rate]  # one second across six chunk joins and a block join
    spectrum = np.abs(np.fft.rfft(segment * np.blackman(len(segment))))
    freqs = np.fft.rfftfreq(len(segment), 1 / rate)
    level_db = 20 * np.log10(spectrum / spectrum.max() + 1e-30)
    assert freqs[np.argmax(spectrum)] == pytest.approx(CARRIER_HZ, abs=1)
    away = np.abs(freqs - CARRIER_HZ) > 20  # beyond the window's main lobe
    assert level_db[away].max() < -110  # no splatter: a joint's click would spread far above this


def _export_on_a_pty(args) -> tuple[int, bytes, str]:
    """Run export with stderr on a pseudo-terminal (as a person at a terminal would); return its status,
    what the terminal showed, and stdout."""
    main, secondary = os.openpty()
    fcntl.ioctl(secondary, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal 100 columns wide
    child = subprocess.Popen([sys.executable, "-m", "ultraglide", "export", *map(str, args)], stdout=subprocess.PIPE,
                             stderr=secondary, stdin=subprocess.DEVNULL, cwd=ROOT)
    os.close(secondary)
    shown = bytearray()
    while True:
        ready, _, _ = select.select([main], [], [], 60)
        if not ready:
            child.kill()
            raise AssertionError("export on a pty printed nothing for 60 s")
        try:
            data = os.read(main, 4096)
        except OSError:  # EIO: the child has closed the terminal
            break
        if not data:
            break
        shown += data
    os.close(main)
    stdout = child.stdout.read().decode()
    return child.wait(timeout=60), bytes(shown), stdout


def test_a_terminal_shows_a_progress_bar_and_a_pipe_shows_none(tmp_path):
    out = tmp_path / "bar.wav"
    status, shown, stdout = _export_on_a_pty(["grating-1mm", "--duration-s", "20", "-o", out])
    assert status == 0
    assert b"export:" in shown and b"frame" in shown and b"%|" in shown  # tqdm's bar: "export:  40%|####  |"
    assert "wrote" in stdout

    piped = run_cli("export", "grating-1mm", "--duration-s", "20", "-o", out, check=True)
    assert piped.stderr == ""  # nothing at all: no bar, no carriage returns
    assert "wrote" in piped.stdout


def test_help_loads_no_numerical_library():
    result = subprocess.run([sys.executable, "-X", "importtime", "-m", "ultraglide", "--help"],
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert result.returncode == 0 and "export" in result.stdout
    loaded = {line.split("|")[-1].strip() for line in result.stderr.splitlines() if line.startswith("import time:")}
    heavy = {name for name in loaded if name.split(".")[0] in {"numpy", "scipy", "numba", "tqdm", "soundfile",
                                                                "matplotlib", "pygame", "PIL"}}
    assert "ultraglide.apps.cli.main" in loaded and not heavy


def test_a_swipe_export_does_not_load_scipy_interpolate():
    # the modules the command loaded, looked at from an atexit hook (as the process ends, whatever way it ends)
    code = ("import atexit, sys, runpy; sys.argv = ['ultraglide', 'export', 'grating-1mm', '--duration-s', '0.2', "
            f"'-o', {str(ROOT / '.no-interpolate.wav')!r}]\n"
            "atexit.register(lambda: print('scipy.interpolate' in sys.modules, 'tqdm' in sys.modules))\n"
            "runpy.run_module('ultraglide', run_name='__main__')")
    try:
        result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    finally:
        (ROOT / ".no-interpolate.wav").unlink(missing_ok=True)
    assert result.stdout.splitlines()[-1] == "False False", result.stderr  # tqdm: stderr is a pipe here


def test_threads_must_be_one_or_more(tmp_path):
    out = tmp_path / "out.wav"
    assert "--threads" in assert_one_line_error(run_cli("export", "grating-1mm", "-o", out, "--threads", "0"))
    assert not out.exists()


INVERSES = {"stretched": "inverse_stretched", "paper": "inverse_uniform", "squeeze-film": "inverse_film_force"}


@pytest.mark.parametrize("model", ["stretched", "paper"])
def test_the_second_export_loads_its_kernels_from_numbas_cache_and_no_other_models(tmp_path, model):
    out = tmp_path / "out.wav"
    argv = ["export", "grating-1mm", "--duration-s", "0.2", "-o", out, "--model", model]
    run_cli(*argv, check=True)  # compiles what is not cached yet (a fresh checkout), and saves it
    second = run_cli(*argv, check=True, env={"NUMBA_DEBUG_CACHE": "1"})
    log = second.stdout + second.stderr
    loaded = {line.split("kernels.")[1].split("-")[0] for line in log.splitlines()
              if "[cache] data loaded" in line and "kernels." in line}
    assert {"envelope", "bilinear", "limit_drive", "modulate", INVERSES[model]} <= loaded, log
    others = {name for key, name in INVERSES.items() if key != model} | {"inverse_table_force"}
    assert not loaded & others, f"{model} loaded other models' inverses: {loaded & others}"  # each costs ~50 ms
    assert "data saved" not in log and "index saved" not in log  # nothing was compiled again


@pytest.mark.parametrize("process, threads", [(True, 7), (False, 3)])
def test_the_writer_process_and_the_writer_threads_write_the_same_samples(tmp_path, process, threads):
    # the library's write_wav both ways: a forked writer process (the default on Linux) and threads of this
    # process; each equals the single-chunk render, over block joins and a last, shorter block
    argv = ["grating-1mm", "--path", "zigzag", "--duration-s", "2.3", "-o", str(tmp_path / "unused.wav")]
    args = build_parser().parse_args(["export", *argv])
    renderer = make_renderer(load_inputs(args), args, args.rate)
    total = int(round((renderer.trajectory.end_s - renderer.trajectory.start_s + renderer.tail_s) * args.rate))
    out, frames_told = tmp_path / "lib.wav", []
    write_wav(offline_stage(renderer), out, total, progress=frames_told.append, threads=threads, process=process)
    written, rate = soundfile.read(out, dtype="float32")
    _, whole = references(argv)
    assert rate == RATE and np.array_equal(written, whole)
    assert frames_told == [RATE, RATE, total - 2 * RATE]  # the progress bar hears of every block once


def _children(pid: int) -> set[int]:
    return {int(child) for child in open(f"/proc/{pid}/task/{pid}/children").read().split()}


def _gone(pid: int) -> bool:
    try:
        return open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the writer is a forked process on Linux only")
def test_the_writer_process_does_not_outlive_a_killed_export(tmp_path):
    out = tmp_path / "long.wav"
    child = start_cli("export", "grating-1mm", "--duration-s", 600, "-o", out, stdout=subprocess.DEVNULL,
                      stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not _children(child.pid) and time.monotonic() < deadline and child.poll() is None:
            time.sleep(0.01)
        writers = _children(child.pid)
        assert writers, "the export started no writer process"
        child.kill()  # SIGKILL: the export cleans nothing up; the writer must notice its pipe close
        child.wait(timeout=60)
        deadline = time.monotonic() + 30
        while not all(_gone(pid) for pid in writers) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert all(_gone(pid) for pid in writers)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
