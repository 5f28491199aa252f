"""Files on a lab's machine (issue 26): no output clobbers what is not a regular file, no input blocks or runs
forever, an output that is also an input is refused, and temporary files left by killed processes go.

Every case uses the real thing: named pipes made with ``os.mkfifo``, device nodes made with ``os.mknod`` in a
temporary directory (copies of /dev/null, /dev/zero and /dev/full, and a block device; root only), Unix sockets,
symbolic and hard links, real signals to real subprocesses.
"""

import contextlib
import hashlib
import os
import select
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
from conftest import ROOT, assert_one_line_error, run_cli, wait_for
from test_inputs import no_hang
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import refuse_overlaps
from ultraglide.apps.experiment.log import read_session, read_trials
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import load_profile
from ultraglide.render.physics.calibration import load_model, read_calibration
from ultraglide.render.physics.errors import ModelError
from ultraglide.render.physics.measurements import read_measurements
from ultraglide.render.touch_log import read_touch_log
from ultraglide.textures.authoring import read_image_luminance
from ultraglide.textures.effects import load_effects
from ultraglide.textures.errors import TextureError
from ultraglide.textures.fileformat import has_texture_metadata, load_texture
from ultraglide.textures.library import resolve_texture

from ultraglide.atomic import MARK, AtomicFile, OutputRefused, remove_leftovers

ROOT_USER = os.geteuid() == 0
NULL, ZERO, FULL, LOOP = os.makedev(1, 3), os.makedev(1, 5), os.makedev(1, 7), os.makedev(7, 0)
needs_root = pytest.mark.skipif(not ROOT_USER, reason="mknod of device nodes needs root")


def special(kind: str, path: Path) -> Path:
    """A real special file at ``path``: a named pipe, a device node, a directory or a Unix socket."""
    if kind == "fifo":
        os.mkfifo(path)
    elif kind in ("null", "zero", "full"):
        os.mknod(path, 0o666 | stat.S_IFCHR, {"null": NULL, "zero": ZERO, "full": FULL}[kind])
    elif kind == "block":
        os.mknod(path, 0o600 | stat.S_IFBLK, LOOP)
    elif kind == "directory":
        path.mkdir()
    elif kind == "socket":
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(path))
        special.sockets.append(server)
    return path


special.sockets = []


@pytest.fixture
def short_tmp():
    """A directory with a short path (a Unix socket's path must fit in 108 bytes)."""
    directory = Path(tempfile.mkdtemp(prefix="ug-"))
    yield directory
    for server in special.sockets:
        server.close()
    special.sockets.clear()
    subprocess.run(["rm", "-rf", str(directory)], check=False)


def kind_of(path: Path) -> str:
    mode = os.lstat(path).st_mode
    return next(name for test, name in ((stat.S_ISFIFO, "fifo"), (stat.S_ISCHR, "char"), (stat.S_ISBLK, "block"),
                                        (stat.S_ISDIR, "directory"), (stat.S_ISSOCK, "socket"),
                                        (stat.S_ISLNK, "link"), (stat.S_ISREG, "file")) if test(mode))


# ---- readers: every loader refuses what is not a regular file, without opening it for reading -----------------
READERS = {  # loader, the exception it raises, the name the special file needs
    "texture file": (load_texture, TextureError, "t.png"),
    "texture by name or path": (resolve_texture, TextureError, "t.png"),
    "author's image": (read_image_luminance, TextureError, "photo.jpg"),
    "--trajectory": (read_touch_log, Exception, "touches.csv"),
    "measurements": (read_measurements, ModelError, "data.csv"),
    "--model CAL.toml": (read_calibration, ModelError, "cal.toml"),
    "--model table:": (lambda path: load_model(f"table:{path}"), ModelError, "table.csv"),
    "--profile": (load_profile, DeviceError, "plate.toml"),
    "--effects": (load_effects, TextureError, "effects.json"),
    "session.json": (lambda path: read_session(path.parent), UsageError, "session.json"),
    "trials.csv": (lambda path: read_trials(path.parent), UsageError, "trials.csv"),
}
KINDS = ["fifo", "zero", "null", "block", "directory", "socket"]
WORDS = {"fifo": "named pipe", "zero": "character device", "null": "character device", "block": "block device",
         "directory": "directory", "socket": "socket"}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("reader", sorted(READERS))
def test_every_reader_refuses_what_is_not_a_regular_file(short_tmp, reader, kind):
    if kind in ("zero", "null", "block") and not ROOT_USER:
        pytest.skip("mknod of device nodes needs root")
    load, error, name = READERS[reader]
    path = special(kind, short_tmp / name)
    with no_hang(30), pytest.raises(error) as raised:
        load(path)
    message = str(raised.value)
    assert "\n" not in message and str(path) in message
    assert WORDS[kind] in message, message
    assert kind_of(path) != "file"  # and it is still what it was


@pytest.mark.parametrize("kind", ["fifo", "zero"])
def test_a_link_to_a_special_file_is_followed_and_refused(short_tmp, kind):
    if kind == "zero" and not ROOT_USER:
        pytest.skip("mknod needs root")
    target = special(kind, short_tmp / "target")
    link = short_tmp / "t.png"
    link.symlink_to(target)
    with no_hang(30), pytest.raises(TextureError, match=WORDS[kind]):
        load_texture(link)
    with no_hang(30):
        assert not has_texture_metadata(link)


def test_a_pipe_swapped_in_after_the_look_is_refused_by_what_was_opened(tmp_path, monkeypatch):
    """The path is looked at (stat) and then opened non-blocking; what was opened is checked again (fstat)."""
    import ultraglide.inputs as inputs

    fifo = special("fifo", tmp_path / "swapped.png")
    regular = os.stat(__file__)
    monkeypatch.setattr(inputs, "check_input", lambda path, what, error: regular)  # the look saw a file
    with no_hang(30), pytest.raises(TextureError, match="named pipe"):
        inputs.open_input(fifo, "texture file", TextureError)


COMMAND_READERS = {  # a command line reading PATH, and the name PATH needs
    "export TEXTURE": (["export", "{}", "-o", "{out}/a.wav", "--duration-s", "0.1"], "t.png"),
    "author IMAGE": (["author", "{}", "-o", "{out}/t.png"], "photo.png"),
    "export --trajectory": (["export", "grating-1mm", "--trajectory", "{}", "-o", "{out}/a.wav"], "log.csv"),
    "export --model CAL.toml": (["export", "grating-1mm", "--model", "{}", "-o", "{out}/a.wav"], "cal.toml"),
    "model --model table:": (["model", "--model", "table:{}", "--ratio", "0.8"], "table.csv"),
    "export --effects": (["export", "grating-1mm", "--effects", "{}", "-o", "{out}/a.wav"], "e.json"),
    "export --profile": (["export", "grating-1mm", "--profile", "{}", "-o", "{out}/a.wav"], "plate.toml"),
    "texture info": (["texture", "info", "{}"], "t.png"),
    "texture compose mask": (["texture", "compose", "mask", "grating-1mm", "{}", "-o", "{out}/m.png"], "mask.png"),
    "calibrate": (["calibrate", "{}"], "data.csv"),
    "play --trajectory": (["play", "grating-1mm", "--trajectory", "{}", "--device", "null"], "log.csv"),
    "experiment --resume": (["experiment", "threshold", "--resume", "{dir}"], "session.json"),
}


@pytest.mark.parametrize("command", sorted(COMMAND_READERS))
def test_no_command_waits_on_a_named_pipe(tmp_path, command):
    """A named pipe nobody writes to, given where a file is read: one line, at once, no output."""
    args, name = COMMAND_READERS[command]
    out = tmp_path / "out"
    out.mkdir()
    session = tmp_path / "session"
    session.mkdir()
    path = special("fifo", (session if command == "experiment --resume" else tmp_path) / name)
    argv = [arg.format(path, out=out, dir=session) for arg in args]
    started = time.monotonic()
    line = assert_one_line_error(run_cli(*argv, timeout=120))
    assert "named pipe" in line and str(path) in line, line
    assert list(out.iterdir()) == [] and kind_of(path) == "fifo"
    assert time.monotonic() - started < 100


@needs_root
def test_commands_refuse_device_nodes_as_inputs(tmp_path):
    zero = special("zero", tmp_path / "zero.png")
    line = assert_one_line_error(run_cli("export", zero, "-o", tmp_path / "a.wav", "--duration-s", "0.1"))
    assert "character device" in line
    table = special("zero", tmp_path / "zero.csv")
    line = assert_one_line_error(run_cli("export", "grating-1mm", "--trajectory", table, "-o", tmp_path / "b.wav"))
    assert "character device" in line
    assert not (tmp_path / "a.wav").exists() and not (tmp_path / "b.wav").exists()


# ---- writers: the one atomic writer, by what the target is ---------------------------------------------------
def written_by(path: Path, content: bytes) -> None:
    with AtomicFile(path) as target:
        target.temporary.write_bytes(content)


def test_a_regular_file_is_replaced_whole_keeping_its_mode(tmp_path):
    path = tmp_path / "out.csv"
    path.write_text("old")
    path.chmod(0o640)
    written_by(path, b"new")
    assert path.read_bytes() == b"new" and stat.S_IMODE(path.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_a_link_stays_a_link_and_its_file_is_replaced(tmp_path):
    real = tmp_path / "real.csv"
    real.write_text("old")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    written_by(link, b"new")
    assert link.is_symlink() and os.readlink(link) == str(real) and real.read_bytes() == b"new"
    dangling = tmp_path / "dangling.csv"
    dangling.symlink_to(tmp_path / "made.csv")
    written_by(dangling, b"made")
    assert dangling.is_symlink() and (tmp_path / "made.csv").read_bytes() == b"made"


@needs_root
def test_a_character_device_is_written_directly_never_replaced(tmp_path):
    null = special("null", tmp_path / "null")
    written_by(null, b"x" * 100_000)
    assert kind_of(null) == "char" and os.stat(null).st_rdev == NULL
    link = tmp_path / "to-null"
    link.symlink_to(null)
    written_by(link, b"discarded")
    assert kind_of(link) == "link" and kind_of(null) == "char"
    full = special("full", tmp_path / "full")
    with pytest.raises(OSError) as raised:
        written_by(full, b"x" * 100_000)
    assert raised.value.filename == str(full) and "space" in raised.value.strerror.lower()
    assert kind_of(full) == "char" and sorted(p.name for p in tmp_path.iterdir()) == ["full", "null", "to-null"]


def test_a_named_pipe_is_written_when_read_and_refused_when_not(tmp_path):
    fifo = special("fifo", tmp_path / "pipe")
    with no_hang(30), pytest.raises(OutputRefused, match="no program is reading"):
        written_by(fifo, b"lost")
    reader, received = pipe_reader(fifo)
    with no_hang(30):
        written_by(fifo, b"through the pipe")
    reader.join(30)
    assert received == [b"through the pipe"] and kind_of(fifo) == "fifo"


def pipe_reader(fifo: Path) -> tuple[threading.Thread, list]:
    """A thread reading ``fifo`` to its end, started and holding it open when this returns (opened without
    waiting for a writer, as a reader that is already there)."""
    received, opened = [], threading.Event()

    def read():
        descriptor = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
        opened.set()
        chunks, deadline = [], time.monotonic() + 120
        while time.monotonic() < deadline:
            select.select([descriptor], [], [], 1.0)
            try:
                chunk = os.read(descriptor, 1 << 16)
            except BlockingIOError:
                continue
            if chunk:
                chunks.append(chunk)
            elif chunks:
                break  # the end, after the data
            else:
                time.sleep(0.01)  # no writer yet
        os.close(descriptor)
        received.append(b"".join(chunks))

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    assert opened.wait(30)
    return thread, received


@pytest.mark.parametrize("kind, words", [("directory", "is a directory"), ("block", "block device"),
                                         ("socket", "socket")])
def test_directories_disks_and_sockets_are_refused(short_tmp, kind, words):
    if kind == "block" and not ROOT_USER:
        pytest.skip("mknod needs root")
    path = special(kind, short_tmp / "target")
    before = os.lstat(path)
    with pytest.raises(OutputRefused, match=words) as raised:
        written_by(path, b"never")
    assert str(path) in str(raised.value) and "\n" not in str(raised.value)
    after = os.lstat(path)
    assert (after.st_mode, after.st_ino, after.st_rdev) == (before.st_mode, before.st_ino, before.st_rdev)
    assert [p.name for p in short_tmp.iterdir()] == ["target"]


def test_a_failed_write_names_the_file_asked_for_never_the_temporary(tmp_path):
    target = tmp_path / "missing-folder" / "out.csv"
    with pytest.raises(OSError) as raised:
        written_by(target, b"x")
    assert raised.value.filename == str(target)
    path = tmp_path / "out.csv"
    with pytest.raises(OSError) as raised, AtomicFile(path) as atomic:
        raise OSError(28, "No space left on device", str(atomic.temporary))
    assert raised.value.filename == str(path) and list(tmp_path.iterdir()) == []


@needs_root
def test_export_writes_to_device_copies_and_leaves_them_devices(tmp_path):
    """The issue's case: as root, `--envelope-csv` or `-o` a copy of /dev/null or /dev/full stays a device."""
    null, full = special("null", tmp_path / "null.wav"), special("full", tmp_path / "full.csv")
    run_cli("export", "grating-1mm", "-o", null, "--envelope-csv", tmp_path / "null.wav", "--duration-s", "0.1",
            check=True)
    line = assert_one_line_error(run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--envelope-csv", full,
                                         "--duration-s", "0.2"))
    assert f"{full}: no space left on device" in line
    assert kind_of(null) == "char" and os.stat(null).st_rdev == NULL
    assert kind_of(full) == "char" and os.stat(full).st_rdev == FULL
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full.csv", "null.wav"]


def test_export_into_pipes(tmp_path):
    """A CSV goes through a pipe a program reads; a WAV cannot (its header is written last): one line."""
    fifo = special("fifo", tmp_path / "env.csv")
    reader, received = pipe_reader(fifo)
    run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--envelope-csv", fifo, "--duration-s", "0.1",
            check=True, timeout=120)
    reader.join(60)
    lines = received[0].decode().splitlines()
    assert lines[0].startswith("t_s,x_mm") and len(lines) > 1000
    wav = special("fifo", tmp_path / "b.wav")
    line = assert_one_line_error(run_cli("export", "grating-1mm", "-o", wav, "--duration-s", "0.1", timeout=120))
    assert "no program is reading" in line
    assert kind_of(fifo) == "fifo" and kind_of(wav) == "fifo"


# ---- temporary files that killed processes left ----------------------------------------------------------------
def leftover(directory: Path, pid: int, host: str | None = None, age_s: float = 0.0) -> Path:
    from ultraglide.atomic.leftovers import _HOST

    path = directory / f".out.{MARK}-{pid}-{host or _HOST}-abcd_123.wav"
    path.write_bytes(b"half")
    if age_s:
        os.utime(path, (time.time() - age_s, time.time() - age_s))
    return path


def dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_leftovers_of_dead_processes_go_and_nothing_else(tmp_path):
    dead = leftover(tmp_path, dead_pid())
    mine = leftover(tmp_path, os.getpid())
    parent = leftover(tmp_path, os.getppid())
    elsewhere = leftover(tmp_path, dead_pid() + 1_000_000, host="ffffff")
    reused = leftover(tmp_path, 1, age_s=0)  # pid 1 runs, but it started before this file: still its maker?
    os.utime(reused, (0, 0))  # written in 1970, long before pid 1 started: that process is not its maker
    other = tmp_path / ".out.something-else.wav"
    other.write_bytes(b"not ours")
    removed = remove_leftovers(tmp_path)
    assert sorted(removed) == sorted([dead, reused])
    assert mine.exists() and parent.exists() and elsewhere.exists() and other.exists()


def test_a_killed_export_leaves_a_recognisable_temporary_that_the_next_write_removes(tmp_path):
    out = tmp_path / "long.wav"
    process = subprocess.Popen([sys.executable, "-m", "ultraglide", "export", "grating-1mm", "-o", str(out),
                                "--duration-s", "600"], cwd=ROOT, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: any(p.stat().st_size > 1_000_000 for p in tmp_path.iterdir()), timeout=120)
        os.kill(process.pid, signal.SIGKILL)
        process.wait(30)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert wait_for(lambda: _writer_gone(tmp_path), timeout=60)  # the forked writer dies with its parent
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(f".long.{MARK}-{process.pid}-") and not out.exists()
    run_cli("export", "grating-1mm", "-o", tmp_path / "next.wav", "--duration-s", "0.1", check=True)
    assert [p.name for p in tmp_path.iterdir()] == ["next.wav"]


def _writer_gone(directory: Path) -> bool:
    """No process still holds a file of ``directory`` open (the killed export's writer process)."""
    for fd_dir in Path("/proc").glob("[0-9]*/fd"):
        with contextlib.suppress(OSError):
            for fd in fd_dir.iterdir():
                with contextlib.suppress(OSError):
                    if os.readlink(fd).startswith(str(directory)):
                        return False
    return True


# ---- an output that is also an input ----------------------------------------------------------------------------
def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_overlaps_are_found_through_links_dots_and_hard_links(tmp_path):
    data = tmp_path / "data.csv"
    data.write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "soft.csv").symlink_to(data)
    os.link(data, tmp_path / "hard.csv")
    for alias in (data, tmp_path / "sub" / ".." / "data.csv", tmp_path / "soft.csv", tmp_path / "hard.csv"):
        with pytest.raises(UsageError, match="which is read"):
            refuse_overlaps({"-o": alias}, {"the data": data})
    for first, second in ((tmp_path / "a.wav", tmp_path / "sub" / ".." / "a.wav"), (data, tmp_path / "soft.csv")):
        with pytest.raises(UsageError, match="are the same file"):
            refuse_overlaps({"-o": first, "--envelope-csv": second})
    refuse_overlaps({"-o": tmp_path / "a.wav", "--envelope-csv": tmp_path / "a.csv"}, {"the data": data})
    refuse_overlaps({"-o": "/dev/null", "--envelope-csv": "/dev/null"})  # a device takes both: discards both


CASES = [
    ["export", "grating-1mm", "-o", "{d}/x.wav", "--envelope-csv", "{d}/x.wav"],
    ["export", "grating-1mm", "-o", "{d}/x.wav", "--envelope-csv", "{d}/sub/../x.wav"],
    ["export", "grating-1mm", "-o", "{d}/x.wav", "--envelope-csv", "{d}/link.wav"],
    ["export", "{d}/t.png", "-o", "{d}/x.wav", "--plot", "{d}/t.png"],
    ["export", "grating-1mm", "--trajectory", "{d}/log.csv", "-o", "{d}/x.wav", "--envelope-csv", "{d}/log.csv"],
    ["author", "{d}/t.png", "-o", "{d}/sub/../t.png"],
    ["author", "{d}/t.png", "-o", "{d}/u.png", "--preview", "{d}/hard.png"],
    ["texture", "compose", "mix", "{d}/t.png", "grating-1mm", "-o", "{d}/t.png"],
    ["texture", "show", "{d}/t.png", "-o", "{d}/t.png"],
    ["calibrate", "{d}/cal.png", "-o", "{d}/cal.toml"],
    ["play", "grating-1mm", "--trajectory", "{d}/log.wav", "--device", "wav:{d}/log.wav"],
    ["play", "grating-1mm", "--trajectory", "{d}/log.csv", "--device", "null", "--envelope-csv", "{d}/sub/../log.csv"],
    ["play", "grating-1mm", "--device", "wav:{d}/x.wav", "--sensors-csv", "{d}/link.wav"],
    ["play", "grating-1mm", "--trajectory", "{d}/log.csv", "--device", "sim", "--finger-log", "{d}/log.csv"],
    ["play", "grating-1mm", "--device", "sim", "--finger-force", "{d}/log.csv", "--finger-log", "{d}/sub/../log.csv"],
    ["plate-sim", "--profile", "{d}/log.csv", "--finger-log", "{d}/log.csv"],
]


@pytest.mark.parametrize("args", CASES)
def test_an_output_that_is_also_an_input_is_refused_before_anything_is_written(tmp_path, args):
    (tmp_path / "sub").mkdir()
    run_cli("texture", "new", "grating", "--size-mm", "20x10", "-o", tmp_path / "t.png", check=True)
    log = "t_s,x_mm,y_mm\n0,1,5\n0.5,10,5\n"
    for name in ("log.csv", "log.wav", "cal.png"):
        (tmp_path / name).write_text(log)
    (tmp_path / "link.wav").symlink_to(tmp_path / "x.wav")  # dangling: the output to be
    os.link(tmp_path / "t.png", tmp_path / "hard.png")
    before = {p.name: digest(p) for p in tmp_path.iterdir() if p.is_file()}
    line = assert_one_line_error(run_cli(*[arg.format(d=tmp_path) for arg in args], timeout=120))
    assert "which is read" in line or "are the same file" in line, line
    after = {p.name: digest(p) for p in tmp_path.iterdir() if p.is_file()}
    assert after == before  # nothing written, nothing changed
    assert not (tmp_path / "x.wav").exists() and not (tmp_path / "x.png").exists()


# ---- plate-sim's link goes only where there is nothing or a link -----------------------------------------------
@needs_root
def test_plate_sim_never_puts_its_link_over_a_device_or_file(tmp_path):
    from ultraglide.devices.sim.pty_plate import PtyPlate

    null = special("null", tmp_path / "null")
    regular = tmp_path / "plate"
    regular.write_text("keep me")
    for path in (null, regular):
        with pytest.raises(DeviceError, match="is not a link"):
            PtyPlate(load_profile(), link_path=str(path))
    assert kind_of(null) == "char" and regular.read_text() == "keep me"


def test_the_temporary_name_is_recognisable(tmp_path):
    target = AtomicFile(tmp_path / "figure.png")
    try:
        name = target.temporary.name
        assert name.startswith(f".figure.{MARK}-{os.getpid()}-") and name.endswith(".png")
        assert repr(target).startswith("AtomicFile(")
    finally:
        target.discard()
    assert list(tmp_path.iterdir()) == []


# ---- logs written as they happen (FILE.csv.part, renamed at the end) --------------------------------------------
def test_a_growing_log_follows_the_same_rule(tmp_path):
    from ultraglide.apps.demo.record import TouchRecorder
    from ultraglide.devices.sim.finger_log import FingerLog

    real = tmp_path / "real.csv"
    real.write_text("old")
    link = tmp_path / "drag.csv"
    link.symlink_to(real)
    recorder = TouchRecorder(link)
    assert recorder.partial == tmp_path / "real.csv.part"
    for t in (0.0, 0.01):
        recorder.touch(t, 1.0, 2.0, None, "grating-1mm", {})
    assert recorder.close() == link and link.is_symlink() and real.read_text().count("\n") == 5
    for maker in (TouchRecorder, FingerLog):
        fifo = special("fifo", tmp_path / f"{maker.__name__}.csv.part")  # a pipe where the .part goes
        with no_hang(30), pytest.raises((OutputRefused, DeviceError), match="not a regular file"):
            maker(tmp_path / f"{maker.__name__}.csv")
        assert kind_of(fifo) == "fifo"
    for maker in (TouchRecorder, FingerLog):
        (tmp_path / "folder.csv").mkdir(exist_ok=True)
        with pytest.raises((OutputRefused, DeviceError), match="is a directory"):
            maker(tmp_path / "folder.csv")


@needs_root
def test_a_growing_log_goes_straight_into_a_device(tmp_path):
    from ultraglide.apps.demo.record import TouchRecorder

    null = special("null", tmp_path / "null.csv")
    recorder = TouchRecorder(null)
    for t in (0.0, 0.01):
        recorder.touch(t, 1.0, 2.0, 0.5, "grating-1mm", {})
    recorder.close()
    assert kind_of(null) == "char" and os.stat(null).st_rdev == NULL
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null.csv"]


def test_texture_effects_may_replace_its_texture_but_not_its_effects_file(tmp_path):
    texture = tmp_path / "t.png"
    run_cli("texture", "new", "grating", "--size-mm", "20x10", "-o", texture, check=True)
    effects = ROOT / "examples" / "pulse.json"
    run_cli("texture", "effects", texture, "--set", effects, "-o", texture, check=True)  # in place, as documented
    copy = tmp_path / "e.png"
    copy.write_bytes(effects.read_bytes())
    before = digest(copy)
    line = assert_one_line_error(run_cli("texture", "effects", texture, "--set", copy, "-o", copy))
    assert "which is read" in line and digest(copy) == before


# ---- a shared folder (sticky, world-writable: /tmp): what another user put there is theirs --------------------
NOBODY = 65534


@pytest.fixture
def shared(tmp_path):
    """A folder like /tmp (mode 1777) holding another user's file, link (to a file of ours) and named pipe."""
    folder = tmp_path / "shared"
    folder.mkdir()
    folder.chmod(0o1777)
    (tmp_path / "ours.csv").write_text("ours\n")
    (folder / "theirs.csv").write_text("theirs\n")
    (folder / "link.csv").symlink_to(tmp_path / "ours.csv")
    os.mkfifo(folder / "pipe.csv")
    for name in ("theirs.csv", "link.csv", "pipe.csv"):
        os.chown(folder / name, NOBODY, NOBODY, follow_symlinks=False)
    return folder


@needs_root
@pytest.mark.parametrize("name, what", [("theirs.csv", "regular file"), ("link.csv", "link"),
                                        ("pipe.csv", "named pipe")])
def test_another_users_file_link_or_pipe_in_a_shared_folder_is_left_alone(shared, name, what):
    """As root a rename replaces anyone's file, and Linux's fs.protected_* guards are off on many machines (and
    never guard a rename): ``--envelope-csv /tmp/theirs.csv`` would have replaced another user's file, or followed
    their link to a file of ours. Refused at the edge, and by the writer itself."""
    path = shared / name
    line = assert_one_line_error(run_cli("export", "grating-1mm", "--duration-s", "0.1", "-o", shared.parent / "a.wav",
                                         "--envelope-csv", path, timeout=120))
    assert f"--envelope-csv {path}: is another user's {what} (uid {NOBODY}) in the shared folder {shared}" in line
    with pytest.raises(OutputRefused, match=f"another user's {what}"):
        AtomicFile(path)
    assert (shared / "theirs.csv").read_text() == "theirs\n" and (shared.parent / "ours.csv").read_text() == "ours\n"
    assert os.lstat(path).st_uid == NOBODY and not (shared.parent / "a.wav").exists()
    assert sorted(os.listdir(shared)) == ["link.csv", "pipe.csv", "theirs.csv"]


@needs_root
def test_ones_own_files_in_a_shared_folder_are_written_as_anywhere(shared):
    (shared / "mine.csv").write_text("old\n")
    written_by(shared / "mine.csv", b"new\n")
    written_by(shared / "new.csv", b"new\n")
    assert (shared / "mine.csv").read_text() == (shared / "new.csv").read_text() == "new\n"
    os.chown(shared, NOBODY, NOBODY)  # a folder of its own is not shared, whoever owns it, without the sticky bit
    shared.chmod(0o777)
    written_by(shared / "theirs.csv", b"replaced\n")
    assert (shared / "theirs.csv").read_text() == "replaced\n"


# ---- a device that takes nothing (a copy of /dev/full), written by each kind of writer -----------------------
FULL_WRITERS = {  # a command line writing {}, a copy of /dev/full; one per writer that reaches a file differently
    "PDF figure (matplotlib)": ["model", "--report", "{}.pdf"],
    "PDF of texture show": ["texture", "show", "edge", "-o", "{}.pdf"],
    "PDF of export --plot": ["export", "grating-1mm", "--duration-s", "0.1", "-o", "{d}/a.wav", "--plot", "{}.pdf"],
    "WAV device of play": ["play", "grating-1mm", "--duration-s", "0.2", "--device", "wav:{}.wav"],
    "WAV of export": ["export", "grating-1mm", "--duration-s", "0.1", "-o", "{}.wav"],
    "growing log of play": ["play", "grating-1mm", "--duration-s", "0.2", "--device", "null", "--envelope-csv",
                            "{}.csv"],
    "profile of plate sweep": ["plate", "sweep", "--steps", "20", "-o", "{}.toml"],
    "texture of texture new": ["texture", "new", "grating", "-o", "{}.png"],
}


@needs_root
@pytest.mark.parametrize("writer", sorted(FULL_WRITERS))
def test_every_writer_into_a_full_device_says_so_in_one_line(tmp_path, writer):
    """A node that refuses every write (``mknod c 1 7``, /dev/full): "no space left", one line, the node a node.
    matplotlib's PDF writer used to hide the reason under a traceback of its own clean-up (``zlib.error``), and
    the WAV device died in the engine process (libsndfile's "System error" on its header)."""
    args = FULL_WRITERS[writer]
    suffix = next(arg for arg in args if "{}" in arg).split("{}")[1]
    full = tmp_path / f"full{suffix}"
    os.mknod(full, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
    argv = [arg.replace("{}" + suffix, str(full)).format(d=tmp_path) for arg in args]
    line = assert_one_line_error(run_cli(*argv, timeout=180))
    assert f"{full}: no space left on device" in line, line
    assert kind_of(full) == "char" and sorted(os.listdir(tmp_path)) == [full.name]


@pytest.mark.parametrize("args", [
    ["model", "--data", "{d}/o/fig9-model-comparison.pdf", "--plots", "{d}/o"],
    ["experiment", "threshold", "grating-1mm", "--reference", "{d}/o/track.png", "--observer", "sim:threshold=0.1",
     "--trials", "5", "--out", "{d}/o"],
    ["experiment", "threshold", "{d}/o/psychometric.png", "--observer", "sim:threshold=0.1", "--trials", "5", "--out",
     "{d}/o"]])
def test_a_file_an_output_folder_would_get_that_is_also_an_input_is_refused(tmp_path, args):
    """Whatever option names what is read (a reference texture, --data), a figure the command writes into its folder
    under that name would have replaced it: refused at the edge, as any output that is also an input."""
    (tmp_path / "o").mkdir()
    run_cli("texture", "new", "grating", "--size-mm", "20x10", "-o", tmp_path / "t.png", check=True)
    for name in ("track.png", "psychometric.png"):
        os.link(tmp_path / "t.png", tmp_path / "o" / name)
    (tmp_path / "o" / "fig9-model-comparison.pdf").write_text("amplitude_um_pp,relative_friction\n0,1\n2,0.5\n")
    before = {p.name: digest(p) for p in (tmp_path / "o").iterdir()}
    line = assert_one_line_error(run_cli(*[arg.format(d=tmp_path) for arg in args], timeout=120))
    assert "which is read" in line, line
    assert {p.name: digest(p) for p in (tmp_path / "o").iterdir()} == before
