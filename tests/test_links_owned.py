"""A link path is owned: a second simulator given a live one's path is refused in one line, and a simulator removes
only the link it made. Real ``ultraglide plate-sim`` processes."""

import os
import signal

from conftest import run_cli
from test_exits import Command, assert_stopped_by, wait_until


def serve(tmp_path, link, name):
    folder = tmp_path / name
    folder.mkdir()
    command = Command(folder, "plate-sim", "--link", link)
    wait_until(lambda: link.is_symlink() and str(link) in command.stdout, "the plate to be served")
    return command


def test_a_link_in_use_by_a_live_simulator_is_refused_and_kept(tmp_path):
    link = tmp_path / "plate"
    first = serve(tmp_path, link, "first")
    try:
        served = os.readlink(link)
        second = run_cli("plate-sim", "--link", link, timeout=120)
        lines = [line for line in second.stderr.splitlines() if line.strip()]
        assert second.returncode != 0 and len(lines) == 1, second.stderr
        assert f"{link} is in use by a live simulated plate (process {first.process.pid}); stop it first" in lines[0]
        assert os.readlink(link) == served and os.path.exists(link)  # the first's link, still to its live pty
        first.signal(signal.SIGTERM)
        assert_stopped_by(first, signal.SIGTERM)
    finally:
        first.kill()
    assert not os.path.lexists(link)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["first"]  # its claim went with it
    # and the path is free again
    again = serve(tmp_path, link, "again")
    try:
        again.signal(signal.SIGTERM)
        assert_stopped_by(again, signal.SIGTERM)
    finally:
        again.kill()


def test_a_simulator_removes_only_the_link_it_made(tmp_path):
    link = tmp_path / "plate"
    first = serve(tmp_path, link, "first")
    try:
        theirs = tmp_path / "theirs"
        theirs.write_text("someone else's")
        link.unlink()
        link.symlink_to(theirs)  # someone put their own link in its place
        first.signal(signal.SIGTERM)
        assert_stopped_by(first, signal.SIGTERM)
    finally:
        first.kill()
    assert os.readlink(link) == str(theirs)
