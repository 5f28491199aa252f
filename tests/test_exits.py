"""Every way out leaves a safe state: real signals to real subprocesses, real full disks (RLIMIT_FSIZE).

A stop signal (SIGINT, SIGTERM, SIGHUP) must rest the plate (zero setpoints, then disable, before the
link closes, with no help from the plate's watchdog), leave no temporary file and no partial output,
and exit with 128 + the signal's number and one line. A write that fails (the kernel refuses to let a
file grow past RLIMIT_FSIZE: EFBIG, as a full disk refuses with ENOSPC) must say so in one line, exit
non-zero and rename nothing into place.
"""

import os
import signal
import subprocess
import time

import numpy as np
import pytest
import soundfile
from conftest import ROOT, assert_one_line_error, run_cli, start_cli
from ultraglide.devices import protocol as p
from ultraglide.render.engine.shm import LAYOUT

STOP_SIGNALS = [signal.SIGINT, signal.SIGTERM, signal.SIGHUP]
DEADLINE_S = 60.0  # generous: the suite runs on a loaded 2-core machine


def wait_until(condition, what, timeout=DEADLINE_S):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


class Command:
    """``ultraglide ARGS`` in a process of its own (forked from the tests' command server, as ``run_cli`` runs it),
    its output in files so that the test can poll it."""

    def __init__(self, tmp_path, *args, env=None):
        self.out_path, self.err_path = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.process = start_cli(*args, stdout=out, stderr=err, env=env)

    @property
    def stdout(self) -> str:
        return self.out_path.read_text()

    @property
    def stderr(self) -> str:
        return self.err_path.read_text()

    def signal(self, signum, repeat=0) -> list[int]:
        """Send ``signum``, then ``repeat`` others 10 ms apart (a burst while it cleans up); returns them all."""
        sent = [signum]
        self.process.send_signal(signum)
        for _ in range(repeat):
            time.sleep(0.01)
            if self.process.poll() is None:
                sent.append(signal.SIGINT if signum != signal.SIGINT else signal.SIGTERM)
                self.process.send_signal(sent[-1])
        return sent

    def wait(self, timeout=DEADLINE_S) -> int:
        try:
            return self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


def assert_stopped_by(command, signum, burst=()):
    """Stopped by ``signum``, or by one of the burst's when the process was blocked in C while they all came
    (Python then handles pending signals lowest number first): 128 + its number, one line naming it."""
    status = command.wait()
    assert status - 128 in {signum, *burst}, command.stderr
    assert "Traceback" not in command.stderr
    last = command.stderr.strip().splitlines()[-1]
    assert last == f"ultraglide: stopped ({signal.Signals(status - 128).name})"


def hidden_files(directory):
    return sorted(path.name for path in directory.iterdir() if path.name.startswith("."))


def size_of_hidden(directory, suffix):
    return sum(path.stat().st_size for path in directory.iterdir() if path.name.startswith(".")
               and path.name.endswith(suffix))


# ---- export -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("signum", STOP_SIGNALS)
def test_a_signalled_export_leaves_neither_output_nor_temporary(tmp_path, signum):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    command = Command(tmp_path, "export", "grating-1mm", "-o", out_dir / "swipe.wav", "--duration-s", "600",
                      "--envelope-csv", out_dir / "env.csv", "--plot", out_dir / "env.png")
    try:
        wait_until(lambda: size_of_hidden(out_dir, ".wav") > 2_000_000, "the export to be writing")
        sent = command.signal(signum, repeat=3)  # the export may be blocked in C (a pipe write) while they come
        assert_stopped_by(command, signum, burst=sent)
    finally:
        command.kill()
    assert list(out_dir.iterdir()) == []


# ---- the plate on a serial link (the `tap` fixture: tests/plate_tap.py) ----------------------------------
@pytest.mark.parametrize("signum", STOP_SIGNALS)
def test_a_signalled_play_on_serial_rests_the_plate(tmp_path, tap, signum):
    command = Command(tmp_path, "play", "grating-1mm", "--device", f"serial:{tap.plate.path}", "--profile", "sim-plate",
                      "--duration-s", "60")
    try:
        wait_until(lambda: tap.plate.simulator.peak_um_pp > 0.5, "the plate to be driven")
        sent = command.signal(signum, repeat=3)  # and a second and third signal during the clean-up
        assert_stopped_by(command, signum, burst=sent)
    finally:
        command.kill()
    tap.assert_rested_by_the_host()


def test_play_on_serial_rests_the_plate_at_its_normal_end(tmp_path, tap):
    command = Command(tmp_path, "play", "grating-1mm", "--device", f"serial:{tap.plate.path}", "--profile", "sim-plate",
                      "--duration-s", "0.5")
    try:
        assert command.wait() == 0, command.stderr
    finally:
        command.kill()
    tap.assert_rested_by_the_host()


@pytest.mark.slow
def test_play_on_serial_rests_the_plate_when_the_command_fails(tap, monkeypatch):
    """An exception in the command's loop (injected: the real renderer never fails on valid input)."""
    from ultraglide.apps.cli.main import main
    from ultraglide.render.engine import Engine

    touch = Engine.touch
    reports = []

    def failing_touch(self, *args, **kwargs):
        reports.append(args)
        if len(reports) == 60:  # half a second into the swipe
            raise RuntimeError("the touch panel went away")
        return touch(self, *args, **kwargs)

    monkeypatch.setattr(Engine, "touch", failing_touch)
    with pytest.raises(RuntimeError, match="touch panel"):
        main(["play", "grating-1mm", "--device", f"serial:{tap.plate.path}", "--profile", "sim-plate",
              "--duration-s", "30"])
    tap.assert_rested_by_the_host()


def test_a_signalled_demo_rests_the_plate(tmp_path, tap):
    command = Command(tmp_path, "demo", "--device", f"serial:{tap.plate.path}", "--profile", "sim-plate", "--windowed",
                      env={"SDL_VIDEODRIVER": "dummy", "SDL_AUDIODRIVER": "dummy"})
    try:
        # nothing touched: the demo's link enables the output, sends 50 ms of zeros, then rests it (ENABLE 0)
        wait_until(lambda: any(kind == p.ENABLE and payload == p.enable_payload(False)
                               for kind, payload, _ in list(tap.frames)), "the demo to connect and rest its output")
        sent = command.signal(signal.SIGTERM, repeat=2)  # the demo may be blocked in SDL's event wait
        assert_stopped_by(command, signal.SIGTERM, burst=sent)
    finally:
        command.kill()
    frames = list(tap.frames)
    disables = [i for i, (kind, payload, _) in enumerate(frames)
                if kind == p.ENABLE and payload == p.enable_payload(False)]
    enables = [i for i, (kind, payload, _) in enumerate(frames)
               if kind == p.ENABLE and payload == p.enable_payload(True)]
    assert disables and enables and frames[disables[-1]][2] == frames[enables[0]][2]  # rested by the host
    assert not tap.plate.simulator.enabled


# ---- the WAV device -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("signum", STOP_SIGNALS)
def test_a_signalled_play_to_wav_keeps_a_whole_recording_that_ends_at_rest(tmp_path, signum):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "live.wav"
    command = Command(tmp_path, "play", "grating-1mm", "--device", f"wav:{out}", "--duration-s", "60")
    try:
        wait_until(lambda: size_of_hidden(out_dir, ".wav") > 96000 * 4, "a second of recording")
        sent = command.signal(signum, repeat=2)
        assert_stopped_by(command, signum, burst=sent)
    finally:
        command.kill()
    assert hidden_files(out_dir) == [], (sorted(path.name for path in out_dir.iterdir()), command.stderr)
    samples, rate = soundfile.read(out, dtype="float32")
    assert len(samples) > rate
    # it was driving the plate (anywhere: on a loaded machine the engine may join the real-time recording late)
    assert np.max(np.abs(samples)) > 0.05
    assert np.max(np.abs(samples[-rate // 200:])) < 1e-3  # and its last 5 ms are at rest: the ramp down ran


# ---- plate-sim ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("signum", STOP_SIGNALS)
def test_a_signalled_plate_sim_removes_its_link(tmp_path, signum):
    link = tmp_path / "plate"
    command = Command(tmp_path, "plate-sim", "--link", link)
    try:
        wait_until(lambda: link.is_symlink() and str(link) in command.stdout, "the plate to be served")
        command.signal(signum)
        assert_stopped_by(command, signum)
    finally:
        command.kill()
    assert not link.is_symlink() and not link.exists()


def test_plate_sim_removes_the_directory_it_made(tmp_path):
    command = Command(tmp_path, "plate-sim")
    try:
        wait_until(lambda: " on " in command.stdout, "the plate to be served")
        path = command.stdout.split(" on ", 1)[1].split(" ", 1)[0]
        assert os.path.islink(path)
        command.signal(signal.SIGTERM)
        assert_stopped_by(command, signal.SIGTERM)
    finally:
        command.kill()
    assert not os.path.lexists(path) and not os.path.exists(os.path.dirname(path))


# ---- full disks: the kernel refuses to let a file grow past RLIMIT_FSIZE (EFBIG) ---------------------------
def run_limited(limit_bytes, *args):
    return run_cli(*args, file_size_limit=limit_bytes)


def assert_refused_and_nothing_left(result, out_dir, name):
    line = assert_one_line_error(result)
    assert f"{name}: file too large" in line and "nothing was saved" in line
    assert [path for path in out_dir.rglob("*") if path.is_file()] == []


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """One run of each writer without a limit, so that no cache (numba's, matplotlib's) is written under one."""
    directory = tmp_path_factory.mktemp("warm")
    run_cli("export", "grating-1mm", "-o", directory / "w.wav", "--duration-s", "0.2", "--plot", directory / "w.png",
            check=True)
    run_cli("texture", "new", "noise", "-o", directory / "noise.png", "--preview", directory / "p.png", check=True)
    return directory


@pytest.mark.parametrize("fmt, sample_bytes", [("float32", 4), ("int24", 3), ("int16", 2)])
def test_export_to_a_full_disk(tmp_path, warm, fmt, sample_bytes):
    out = tmp_path / "swipe.wav"
    half_a_second = 96000 * sample_bytes // 2  # the export is over a second long
    result = run_limited(half_a_second, "export", "grating-1mm", "-o", out, "--duration-s", "1", "--format", fmt)
    assert_refused_and_nothing_left(result, tmp_path, "swipe.wav")


def test_export_renames_no_output_when_another_fails(tmp_path):
    """The WAV and the CSV are complete but the plot does not fit: none of the three appears."""
    names = {"wav": tmp_path / "swipe.wav", "csv": tmp_path / "env.csv", "png": tmp_path / "env.png"}
    args = ["export", "grating-1mm", "-o", names["wav"], "--duration-s", "0.3", "--format", "int16",
            "--envelope-csv", names["csv"], "--plot", names["png"]]
    run_cli(*args, check=True)
    sizes = {key: path.stat().st_size for key, path in names.items()}
    for path in names.values():
        path.unlink()
    largest = max(sizes, key=sizes.get)
    assert sizes[largest] > max(size for key, size in sizes.items() if key != largest)
    result = run_limited(sizes[largest] - 1, *args)
    assert_refused_and_nothing_left(result, tmp_path, names[largest].name)


def test_play_to_wav_on_a_full_disk(tmp_path):
    out = tmp_path / "live.wav"
    # the limit lets the engine's shared-memory segment (0.58 MB in /dev/shm, which the file-size limit also
    # counts) be made, and stops the 0.77 MB recording of a 2 s swipe at 1.75 s
    assert LAYOUT.size * 8 < 96000 * 4 * 7 // 4
    result = run_limited(96000 * 4 * 7 // 4, "play", "grating-1mm", "--device", f"wav:{out}", "--duration-s", "2")
    assert_refused_and_nothing_left(result, tmp_path, "live.wav")


def test_texture_outputs_on_a_full_disk(tmp_path, warm):
    source = warm / "noise.png"
    result = run_limited(source.stat().st_size // 2, "texture", "new", "noise", "-o", tmp_path / "t.png")
    assert_refused_and_nothing_left(result, tmp_path, "t.png")
    result = run_limited(source.stat().st_size // 2, "author", source, "-o", tmp_path / "a.png")
    assert_refused_and_nothing_left(result, tmp_path, "a.png")


def test_calibration_and_figures_on_a_full_disk(tmp_path, warm):
    data = ROOT / "apps" / "data" / "monnoyer2018-fit.csv"
    result = run_limited(64, "calibrate", data, "-o", tmp_path / "cal.toml")
    assert_refused_and_nothing_left(result, tmp_path, "cal.toml")
    figures = tmp_path / "figs"
    result = run_limited(20_000, "model", "--plots", figures)
    line = assert_one_line_error(result)
    assert "file too large" in line and str(figures) in line
    assert [path for path in figures.rglob("*") if path.is_file()] == []


def test_an_output_that_is_a_directory_is_refused_and_nothing_is_left(tmp_path):
    (tmp_path / "swipe.wav").mkdir()
    result = run_cli("export", "grating-1mm", "-o", tmp_path / "swipe.wav", "--duration-s", "0.2")
    line = assert_one_line_error(result)
    assert "swipe.wav" in line
    assert sorted(path.name for path in tmp_path.iterdir()) == ["swipe.wav"]


# ---- bad input: usage, exit 2 ------------------------------------------------------------------------------------

def bad_inputs(folder):
    """Files a person may hand a command that it cannot use, written here: not an image, broken TOML, CSVs without
    the columns their header must name."""
    (folder / "notes.png").write_text("not a picture\n")
    (folder / "broken.toml").write_text("x = [\n")
    (folder / "points.csv").write_text("a,b\n1,2\n")
    (folder / "log.csv").write_text("t_s,x_mm\n0,1\n")
    (folder / "recording.csv").write_text("time_s,force_n\n0,0.5\n")
    (folder / "early.ahap").write_text('{"Pattern": [{"Event": {"Time": -1, "EventType": "HapticTransient"}}]}')
    (folder / "scene.gltf").write_text('{"asset": 3}')
    return folder


# (the command line, the file its line must name); {d}: the folder of bad inputs, {o}: a folder for outputs
BAD_INPUT_FILES = [
    (["export", "{d}/notes.png", "-o", "{o}/a.wav"], "notes.png"),
    (["export", "{d}/missing.png", "-o", "{o}/a.wav"], "missing.png"),
    (["play", "{d}/notes.png", "--device", "null", "--duration-s", "0.1"], "notes.png"),
    (["texture", "info", "{d}/notes.png"], "notes.png"),
    (["author", "{d}/notes.png", "-o", "{o}/t.png"], "notes.png"),
    (["model", "--model", "{d}/broken.toml"], "broken.toml"),
    (["model", "--model", "table:{d}/points.csv"], "points.csv"),
    (["calibrate", "{d}/points.csv", "-o", "{o}/c.toml"], "points.csv"),
    (["calibrate", "{d}/broken.toml", "-o", "{o}/c.toml"], "broken.toml"),
    (["calibrate", "{d}/recording.csv", "--compare"], "recording.csv"),
    (["export", "grating-1mm", "--model", "{d}/broken.toml", "-o", "{o}/a.wav"], "broken.toml"),
    (["export", "grating-1mm", "--trajectory", "{d}/log.csv", "-o", "{o}/a.wav"], "log.csv"),
    (["export", "grating-1mm", "--profile", "{d}/broken.toml", "-o", "{o}/a.wav"], "broken.toml"),
    (["plate-sim", "--finger", "{d}/broken.toml"], "broken.toml"),
    (["rig", "check", "{d}/broken.toml"], "broken.toml"),
    (["experiment", "check", "{d}/broken.toml"], "broken.toml"),
    (["texture", "effects", "grating-1mm", "--set", "{d}/early.ahap", "-o", "{o}/e.png"], "early.ahap"),
    (["texture", "import", "{d}/scene.gltf", "-o", "{o}/i.png"], "scene.gltf"),
]


# (the command line, words its line must hold): values the plate's profile refuses, said before a device is touched
BAD_VALUES = [
    (["play", "grating-1mm", "--device", "null", "--duration-s", "0.1", "--carrier-hz", "30000"], "20000-28000 Hz"),
    (["play", "grating-1mm", "--device", "wav:{o}/p.wav", "--duration-s", "0.1", "--carrier-hz", "19000"],
     "20000-28000 Hz"),
    (["export", "grating-1mm", "--carrier-hz", "30000", "-o", "{o}/a.wav"], "20000-28000 Hz"),
]


@pytest.mark.parametrize("args, words", BAD_VALUES, ids=[" ".join(a[:2]) + " " + a[-1] for a, _ in BAD_VALUES])
def test_a_carrier_outside_the_plates_range_is_usage_one_line_and_exit_2(tmp_path, args, words):
    outputs = tmp_path / "out"
    outputs.mkdir()
    result = run_cli(*[arg.format(o=outputs) for arg in args], timeout=120)
    line = assert_one_line_error(result)
    assert result.returncode == 2 and words in line and result.stdout == "", (result.returncode, line)
    assert list(outputs.iterdir()) == []  # nothing written


@pytest.mark.parametrize("args, named", BAD_INPUT_FILES, ids=[" ".join(a[:2]) + " " + n for a, n in BAD_INPUT_FILES])
def test_a_bad_input_file_is_usage_one_line_and_exit_2(tmp_path, args, named):
    inputs, outputs = tmp_path / "in", tmp_path / "out"
    inputs.mkdir()
    outputs.mkdir()
    bad_inputs(inputs)
    result = run_cli(*[arg.format(d=inputs, o=outputs) for arg in args], timeout=120)
    line = assert_one_line_error(result)
    assert result.returncode == 2 and named in line and result.stdout == "", (result.returncode, line)
    assert list(outputs.iterdir()) == []  # nothing written


def test_an_output_that_cannot_be_written_is_not_usage_and_exits_1(tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir()
    result = run_cli("export", "grating-1mm", "-o", folder, "--duration-s", "0.1")
    assert result.returncode == 1 and "is a directory" in assert_one_line_error(result)
    assert list(folder.iterdir()) == []
