"""A failed or stopped output leaves no part file: a live log on a full disk, a hangup to a command and its engine.
"""

import os
import signal

from conftest import assert_one_line_error, run_cli
from test_exits import Command, assert_stopped_by, wait_until
from test_supervision import engine_of


def test_play_envelope_csv_on_a_full_disk_leaves_no_part(tmp_path):
    log = tmp_path / "env.csv"
    # the limit lets the engine's shared memory be made (0.58 MB in /dev/shm, which the limit also counts) and stops
    # the envelope log (some 0.7 MB a second on sim) within the 4 s swipe
    result = run_cli("play", "grating-1mm", "--device", "sim", "--duration-s", "4", "--envelope-csv", log,
                     file_size_limit=1_000_000)
    line = assert_one_line_error(result)
    assert "env.csv: file too large" in line, line
    assert list(tmp_path.iterdir()) == []


def test_a_hangup_to_play_and_its_engine_rests_the_plate_from_the_engine(tmp_path, tap):
    """A terminal's hangup reaches the command and its engine together: the engine takes SIGHUP as SIGTERM (ramps
    down, zero setpoints, DISABLE), rather than dying of it."""
    command = Command(tmp_path, "play", "grating-1mm", "--device", f"serial:{tap.plate.path}",
                      "--profile", "sim-plate", "--duration-s", "60")
    try:
        wait_until(lambda: tap.plate.simulator.peak_um_pp > 0.5, "the plate to be driven")
        engine = engine_of(command.process.pid)
        os.kill(engine, signal.SIGHUP)
        command.process.send_signal(signal.SIGHUP)
        assert_stopped_by(command, signal.SIGHUP)
    finally:
        command.kill()
    assert "engine" not in command.stderr, command.stderr
    tap.assert_rested_by_the_host()
