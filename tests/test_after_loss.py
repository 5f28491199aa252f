"""A plate made safe after the process that drove it was lost (devices/after_loss.py), on the simulated plate
served on a real pty: the disable gets through whatever half-frame the lost process left on the link, and a
frozen process's port is borrowed, so the disable goes out while that process still holds the port."""

import os
import signal
import subprocess
import sys

import pytest
from test_exits import wait_until
from ultraglide.devices import protocol as p
from ultraglide.devices.after_loss import borrow_port, disable_serial_plate
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.serial.link import open_port

BAUD = 921600
HALF_A_FRAME = p.encode_frame(p.SETPOINTS, 7, bytes(200))[:90]  # a writer cut off mid-frame: no 0x00 in it


def enable(tap):
    """The plate enabled (as a host that drove it left it), over a port opened and closed again."""
    link = open_port(tap.plate.path, BAUD)
    try:
        link.write(p.encode_frame(p.ENABLE, 1, p.enable_payload(True)))
        link.flush()
    finally:
        link.close()
    wait_until(lambda: tap.plate.simulator.enabled, "the plate enabled")


def test_a_half_written_frame_does_not_swallow_the_disable(tap):
    assert 0 not in HALF_A_FRAME
    enable(tap)
    link = open_port(tap.plate.path, BAUD)
    link.write(HALF_A_FRAME)  # the lost process's last write, cut short
    link.flush()
    link.close()
    words = disable_serial_plate(tap.plate.path, BAUD)
    assert words.startswith("ENABLE 0 sent and acknowledged by the plate"), words
    assert len(tap.disables()) == 1 and not tap.plate.simulator.enabled


HOLDER = """
import os, signal, sys
from ultraglide.devices.serial.link import open_port
link = open_port(sys.argv[1], int(sys.argv[2]))
link.write(bytes.fromhex(sys.argv[3]))  # cut off mid-frame, then frozen holding the port
link.flush()
print("holding", flush=True)
os.kill(os.getpid(), signal.SIGSTOP)
"""


def test_a_frozen_process_port_is_borrowed_and_the_disable_sent_while_it_holds_it(tap):
    enable(tap)
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, tap.plate.path, str(BAUD), HALF_A_FRAME.hex()],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "holding\n"
        wait_until(lambda: open(f"/proc/{holder.pid}/stat").read().rsplit(")", 1)[1].split()[0] == "T",
                   "the holder stopped")
        with pytest.raises(DeviceError, match="in use"):  # its lock holds: the port cannot be opened again
            open_port(tap.plate.path, BAUD)
        assert borrow_port("sim", holder.pid) is None
        assert borrow_port(f"serial:{tap.plate.path}", os.getpid()) is None  # this process holds no such port
        borrowed = borrow_port(f"serial:{tap.plate.path}", holder.pid)
        assert borrowed is not None
        borrowed.send()
        wait_until(lambda: tap.disables(), "the disable at the plate")  # the holder still there, stopped
        assert holder.poll() is None and not tap.plate.simulator.enabled
        holder.send_signal(signal.SIGKILL)
        holder.wait(30)
        words = borrowed.finish()
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait(30)
    assert words.startswith("ENABLE 0 sent on the frozen engine's own port before its end and acknowledged "
                            "by the plate"), words
    assert len(tap.disables()) == 1
    open_port(tap.plate.path, BAUD).close()  # and the port is free again, the borrowed file closed
