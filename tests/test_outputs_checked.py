"""Outputs checked at the edge (issue 26): every option that names something a command writes is checked before
the command does any work, so a directory, a disk, a socket, a named pipe nobody reads, a missing folder or one
that cannot be written is refused in one line naming the option, not after ten minutes of rendering.

The parser is walked: an option that takes a path must be a checked output (``output_option``) or a known
input, so a new output option cannot go unchecked. Every checked output is then given each bad target for real
(directories, named pipes made with ``os.mkfifo``, device nodes made with ``os.mknod``, Unix sockets).
"""

import argparse
import contextlib
import io
import json
import os
import shutil
import socket
import stat
import subprocess
import tempfile
from pathlib import Path

import pytest
from conftest import assert_one_line_error, run_cli
from test_inputs import no_hang
from ultraglide.apps.cli.main import main
from ultraglide.apps.cli.options import OUTPUTS
from ultraglide.apps.cli.parser import build_parser

from ultraglide.atomic import AtomicFile, OutputRefused, check_output, check_output_folder, release_checked

ROOT_USER = os.geteuid() == 0

# Options that take text but write nothing: what they read, or words. A new option taking a path must be added
# here (if it is read) or declared with output_option (if it is written), which main checks before the command.
READ_OR_WORDS = {
    "lies": "words: a frame's field and the value a simulated plate reports for it",
    "touch_panel": "an evdev node or a FIFO of its records, read", "touch_range": "words: an axis's range",
    "add": "an effects file read", "set": "an effects file read", "data": "measured points read",
    "effects": "an effects file read", "image": "an image read", "inputs": "textures read", "mask": "an image read",
    "other": "a texture read", "texture": "a texture read", "textures": "textures read",
    "trajectory": "a touch log read", "model": "a model name or a file read", "profile": "a profile read",
    "reference": "a texture read", "finger": "a law's name", "finger_force": "a force or walk",
    "observer": "a simulated observer's settings", "participant": "a code", "session": "a label",
    "rules": "a rule's name", "breaks": "a rule's name", "sensor": "an audio input",
    "device": "a plate driver's URL, where wav:PATH is refused (else it is a checked output)",
    "host": "an address listened on", "unix": "a Unix socket made by serve, which refuses anything already there",
    "design": "an experiment's DESIGN.toml read", "rig": "a rig file read", "rig_file": "a rig file read",
    "scene": "a glTF scene read", "material": "a material's name or index", "name": "a texture's name",
}


def leaves(parser: argparse.ArgumentParser, words=()):
    """Each command's own parser (``texture new grating``), with the words that reach it."""
    commands = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    if not commands:
        yield words, parser
    for action in commands:
        for name, sub in action.choices.items():
            yield from leaves(sub, (*words, name))


def outputs_of(parser) -> dict:
    return parser.get_default(OUTPUTS) or {}


def test_every_option_taking_a_path_is_a_checked_output_or_a_known_input():
    unknown = []
    for words, parser in leaves(build_parser()):
        outputs = outputs_of(parser)
        for action in parser._actions:
            takes_text = action.nargs != 0 and action.choices is None and action.type in (None, str)
            if takes_text and action.dest not in outputs and action.dest not in {*READ_OR_WORDS, "help"}:
                unknown.append(f"{' '.join(words)} {'/'.join(action.option_strings) or action.dest}")
    assert not unknown, (f"options taking text that are neither known inputs nor checked outputs: {unknown}; "
                         "declare an output with output_option (main checks it before the command runs), or add "
                         "an input to READ_OR_WORDS")


# a command line that would do real work, the output under test added to it; {ok}: a folder that takes files
BASE = {
    ("model",): ["model"],
    ("calibrate",): ["calibrate", "{ok}/data.csv"],
    ("author",): ["author", "{ok}/image.png", "-o", "{ok}/t.png"],
    ("texture", "show"): ["texture", "show", "grating-1mm", "-o", "{ok}/s.png"],
    ("texture", "effects"): ["texture", "effects", "grating-1mm", "--clear", "-o", "{ok}/t.png"],
    ("texture", "compose", "mask"): ["texture", "compose", "mask", "grating-1mm", "{ok}/mask.png", "-o", "{ok}/t.png"],
    ("texture", "compose", "tile"): ["texture", "compose", "tile", "grating-1mm", "dots", "--region", "0,0,10,10",
                                     "-o", "{ok}/t.png"],
    ("export",): ["export", "grating-1mm", "-o", "{ok}/a.wav", "--duration-s", "600"],
    ("play",): ["play", "grating-1mm", "--device", "null", "--duration-s", "600"],
    ("plate-sim",): ["plate-sim"],
    ("firmware", "build"): ["firmware", "build", "--rebuild"],
    ("plate", "sweep"): ["plate", "sweep", "-o", "{ok}/p.toml"],
    ("demo",): ["demo", "--windowed"],
    ("experiment", "threshold"): ["experiment", "threshold", "grating-1mm", "--trials", "3", "--observer",
                                  "sim:threshold=0.2", "--out", "{ok}/session"],
    ("experiment", "constant"): ["experiment", "constant", "--preset", "vezzoli2015", "--observer",
                                 "sim:threshold=0.2", "--out", "{ok}/session"],
    ("experiment", "run"): ["experiment", "run", "{ok}/design.toml", "--participant", "P01", "--out", "{ok}/session"],
    ("latency",): ["latency"],
    ("texture", "import"): ["texture", "import", "{ok}/scene.glb", "-o", "{ok}/t.png"],
    ("texture", "export-gltf"): ["texture", "export-gltf", "grating-1mm", "-o", "{ok}/t.glb"],
    ("serve",): ["serve", "--device", "null", "--port", "0"],
}


def base_command(words: tuple) -> list[str]:
    if words in BASE:
        return BASE[words]
    if words[:2] == ("texture", "new"):
        return [*words, "-o", "{ok}/t.png"]
    if words[:2] == ("texture", "compose"):
        return [*words, "grating-1mm", "dots", "-o", "{ok}/t.png"]
    raise AssertionError(f"{' '.join(words)} writes files: give it a command line in BASE")


CHECKED = sorted((words, option, kind) for words, parser in leaves(build_parser())
                 for option, kind, _ in outputs_of(parser).values())


def bad_targets(kind: str, bad: Path) -> list[tuple[str, str]]:
    """(target, words the refusal says) for an output of ``kind``, each made for real in ``bad``."""
    directory, fifo, regular = bad / "folder.out", bad / "pipe.out", bad / "file.out"
    directory.mkdir()
    os.mkfifo(fifo)
    regular.write_text("keep")
    if kind == "folder":
        return [(str(fifo), "not a folder"), (str(regular), "not a folder"), (f"{regular}/new", "not a folder")]
    if kind == "link":
        return [(str(directory), "not a link"), (f"{bad}/missing/link", "does not exist")]
    targets = [(str(directory), "is a directory"), (f"{bad}/missing/out.csv", "does not exist"),
               (str(fifo), "no program is reading"), (f"{regular}/out.csv", "not a folder")]
    if ROOT_USER:
        os.mknod(bad / "disk.out", 0o600 | stat.S_IFBLK, os.makedev(7, 0))
        targets.append((str(bad / "disk.out"), "block device"))
    if kind == "device":
        targets = [(f"wav:{target}", words) for target, words in targets]
    return targets


def snapshot(directory: Path) -> dict:
    return {str(p.relative_to(directory)): (os.lstat(p).st_mode, os.lstat(p).st_ino) for p in directory.rglob("*")}


@pytest.mark.parametrize("words, option, kind", CHECKED, ids=[f"{' '.join(w)} {o}" for w, o, _ in CHECKED])
def test_every_output_is_refused_before_any_work(tmp_path, capsys, monkeypatch, words, option, kind):
    monkeypatch.delenv("DISPLAY", raising=False)  # were a check missing, no window would open either
    ok, bad = tmp_path / "ok", Path(tempfile.mkdtemp(prefix="ug-"))  # short: a socket's path fits 108 bytes
    ok.mkdir()
    try:
        targets = bad_targets(kind, bad)
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(bad / "socket.out"))
        if kind not in ("folder", "link"):
            targets.append((("wav:" if kind == "device" else "") + str(bad / "socket.out"), "socket"))
        before = snapshot(bad)
        for target, expected in targets:
            argv = [arg.format(ok=ok) for arg in base_command(words)]
            if option in argv:  # a required output given in the base line: the bad one replaces it
                del argv[argv.index(option):argv.index(option) + 2]
            with no_hang(60):
                status = main([*argv, option, target])
            error = capsys.readouterr().err.strip()
            assert status == 1 and "\n" not in error, (argv, error)
            assert f"error: {option} {target}: " in error and expected in error, error
            assert list(ok.iterdir()) == [] and snapshot(bad) == before  # nothing written, nothing replaced
        server.close()
    finally:
        shutil.rmtree(bad)


def test_the_issues_cases_end_to_end(tmp_path):
    """A refused ``calibrate -o DIR`` fitted first, and an export rendered ten minutes before its plot failed."""
    data = tmp_path / "data.csv"
    data.write_text("amplitude_um_pp,relative_friction\n" + "".join(f"{a},{1 - 0.08 * a}\n" for a in range(8)))
    (tmp_path / "cal.toml").mkdir()
    (tmp_path / "plot.png").mkdir()
    line = assert_one_line_error(run_cli("calibrate", data, "-o", tmp_path / "cal.toml", "--bootstrap", "0"))
    assert f"-o {tmp_path / 'cal.toml'}: is a directory" in line
    line = assert_one_line_error(run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--duration-s", "3600",
                                         "--plot", tmp_path / "plot.png", timeout=120))
    assert f"--plot {tmp_path / 'plot.png'}: is a directory" in line
    assert sorted(os.listdir(tmp_path)) == ["cal.toml", "data.csv", "plot.png"]


def test_the_calibrations_figures_beside_it_are_checked_too(tmp_path):
    data = tmp_path / "data.csv"
    data.write_text("amplitude_um_pp,relative_friction\n" + "".join(f"{a},{1 - 0.08 * a}\n" for a in range(8)))
    (tmp_path / "cal.pdf").mkdir()
    line = assert_one_line_error(run_cli("calibrate", data, "-o", tmp_path / "cal.toml", "--bootstrap", "0"))
    assert f"-o (its PDF beside it) {tmp_path / 'cal.pdf'}: is a directory" in line
    assert sorted(os.listdir(tmp_path)) == ["cal.pdf", "data.csv"]


def test_a_reader_that_stops_at_its_first_end_of_file_gets_the_whole_output(tmp_path):
    """``cat PIPE`` ends at the first end of file: the check's look at the pipe must not give it one."""
    fifo = tmp_path / "envelope.csv"
    os.mkfifo(fifo)
    received = tmp_path / "received.csv"
    with open(received, "wb") as sink:
        reader = subprocess.Popen(["cat", str(fifo)], stdout=sink)
        try:
            run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--envelope-csv", fifo, "--duration-s", "0.2",
                    check=True, timeout=120)
            assert reader.wait(timeout=60) == 0
        finally:
            if reader.poll() is None:
                reader.kill()
                reader.wait()
    lines = received.read_text().splitlines()
    assert lines[0].startswith("t_s,") and len(lines) > 2000  # 0.2 s at 12 000 rows a second, and the tail


def test_a_held_pipe_is_the_one_written_and_released_at_the_end(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    descriptor = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # a reader
    try:
        check_output(fifo, "--envelope-csv")
        with AtomicFile(fifo) as target:
            assert target.direct
            with open(target.temporary, "w") as stream:
                stream.write("a,b\n")
        check_output(fifo, "--envelope-csv")  # checked, never taken (written in another process)
        release_checked()
        assert os.read(descriptor, 100) == b"a,b\n"
        assert os.read(descriptor, 100) == b""  # every writer gone: the end
    finally:
        os.close(descriptor)
        release_checked()


@pytest.mark.skipif(not ROOT_USER, reason="mknod needs root")
def test_a_device_node_stays_writable_and_is_never_replaced(tmp_path):
    null = tmp_path / "null.csv"
    os.mknod(null, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    check_output(null, "--envelope-csv")
    check_output(null, "--record", kind="log")
    run_cli("export", "grating-1mm", "-o", tmp_path / "a.wav", "--envelope-csv", null, "--duration-s", "0.1",
            check=True)
    assert stat.S_ISCHR(os.lstat(null).st_mode) and os.lstat(null).st_rdev == os.makedev(1, 3)


def refusal_as_a_user(argv: list[str]) -> tuple[int, str]:
    """``main(argv)``'s status and error line, run by a user who may not write everywhere: this process when it
    is not root, else a child of it that became ``nobody`` (root writes anywhere)."""
    if not ROOT_USER:
        stream = io.StringIO()
        with contextlib.redirect_stderr(stream):
            return main(argv), stream.getvalue().strip()
    read, write = os.pipe()
    child = os.fork()
    if child == 0:  # pragma: no cover - the child reports through the pipe
        status = 99
        try:
            os.setgroups([])
            os.setgid(65534)
            os.setuid(65534)
            stream = io.StringIO()
            with contextlib.redirect_stderr(stream):
                status = main(argv)
            os.write(write, json.dumps([status, stream.getvalue().strip()]).encode())
        finally:
            os._exit(status)
    os.close(write)
    with os.fdopen(read) as reply:
        answer = reply.read()
    os.waitpid(child, 0)
    return tuple(json.loads(answer))


@pytest.fixture
def open_tmp():
    """A folder anyone may reach (pytest's own are its user's only)."""
    directory = Path(tempfile.mkdtemp(prefix="ug-"))
    directory.chmod(0o755)
    yield directory
    shutil.rmtree(directory)


def test_a_folder_that_cannot_take_a_file_is_refused(open_tmp):
    locked = open_tmp / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    for argv, option in ((["export", "grating-1mm", "-o", f"{locked}/a.wav", "--duration-s", "600"], "-o"),
                         (["model", "--plots", f"{locked}/figures"], "--plots"),
                         (["play", "grating-1mm", "--device", "null", "--envelope-csv", f"{locked}/e.csv"],
                          "--envelope-csv")):
        with no_hang(60):
            status, line = refusal_as_a_user(argv)
        assert status == 1 and "\n" not in line, line
        assert f"{option} {locked}" in line and "cannot write in its folder" in line and "permission" in line, line
    assert list(locked.iterdir()) == []


def test_the_check_alone_refuses_each_kind_in_one_line(tmp_path):
    (tmp_path / "dir").mkdir()
    os.mkfifo(tmp_path / "fifo")
    cases = [(lambda: check_output(tmp_path / "dir", "-o"), "-o"),
             (lambda: check_output(tmp_path / "fifo", "-o", kind="wav"), "no program is reading"),
             (lambda: check_output_folder(tmp_path / "fifo" / "x", "--out"), "not a folder"),
             (lambda: check_output(tmp_path / "nul\0l", "-o"), "not a usable file name")]
    (tmp_path / "log.csv.part").mkdir()
    cases.append((lambda: check_output(tmp_path / "log.csv", "--record", kind="log"), "log.csv.part is a directory"))
    for check, words in cases:
        with pytest.raises(OutputRefused, match=words) as raised:
            check()
        assert "\n" not in str(raised.value)
    check_output_folder(tmp_path / "new" / "deeper", "--out")  # made with its parents, later
    check_output(tmp_path / "new.wav", "-o", kind="wav")
    assert sorted(os.listdir(tmp_path)) == ["dir", "fifo", "log.csv.part"]  # the probe file is gone


def test_a_wav_through_a_pipe_a_program_reads_is_refused_before_the_work(tmp_path):
    fifo = tmp_path / "a.wav"
    os.mkfifo(fifo)
    descriptor = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # a program reading it
    try:
        with pytest.raises(OutputRefused, match="a WAV file cannot go through one"):
            check_output(fifo, "-o", kind="wav")
        assert os.read(descriptor, 10) == b""  # nothing was written into it, and it was let go
    finally:
        os.close(descriptor)


FOLDER_FILES = sorted((words, option, also) for words, parser in leaves(build_parser())
                      for option, kind, also in outputs_of(parser).values() if kind == "folder" and also)


def test_the_folders_with_files_of_known_names_are_the_ones_expected():
    assert {(" ".join(words), option) for words, option, _ in FOLDER_FILES} == {
        ("model", "--plots"), ("experiment threshold", "--out"), ("experiment threshold", "--resume"),
        ("experiment constant", "--out"), ("experiment constant", "--resume"), ("experiment run", "--out")}


@pytest.mark.parametrize("words, option, names", FOLDER_FILES, ids=[f"{' '.join(w)} {o}" for w, o, _ in FOLDER_FILES])
def test_every_file_a_folder_output_writes_is_checked_before_any_work(tmp_path, capsys, monkeypatch, words, option,
                                                                      names):
    """A file the command writes into an output folder (``model --plots DIR``'s fig7, a session's result.json) that
    is a named pipe nobody reads or a directory is refused before the first figure is drawn, naming that file."""
    monkeypatch.delenv("DISPLAY", raising=False)
    ok, folder = tmp_path / "ok", tmp_path / "folder"
    ok.mkdir()
    folder.mkdir()
    for number, name in enumerate(names):
        path = folder / name
        if number % 2:
            path.mkdir()
        else:
            os.mkfifo(path)
        argv = [arg.format(ok=ok) for arg in base_command(words)]
        with no_hang(60):
            status = main([*argv, option, str(folder)])
        error = capsys.readouterr().err.strip()
        expected = "is a directory" if number % 2 else "is a named pipe that no program is reading"
        assert status == 1 and "\n" not in error, (argv, error)
        assert f"error: {option} {path}: {expected}" in error, error
        assert list(ok.iterdir()) == [] and sorted(os.listdir(folder)) == [name]  # nothing drawn before it
        (path.rmdir if number % 2 else path.unlink)()
