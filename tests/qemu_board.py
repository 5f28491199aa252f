"""What the QEMU board tests share: a board's events waited for, its HELLO asked over its link, and a fault injected
into a running board. (Their fixture ``one_qemu``, one QEMU at a time across the workers, is in conftest.py.)"""

from __future__ import annotations

import contextlib
import queue
import time

from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.qemu import QemuPlate


def next_event(plate: QemuPlate, names: tuple[str, ...], timeout: float = 30.0) -> dict:
    """The board's next event named one of ``names`` (the others passed over), within ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(queue.Empty):
            event = plate.events.get(timeout=0.2)
            if event["event"] in names:
                return event
    raise AssertionError(f"no {' or '.join(names)} event within {timeout} s")


def said_in_hello(plate: QemuPlate) -> p.HelloReply:
    """The board's HELLO_REPLY, asked over its link now."""
    from test_firmware_qemu import Link

    link = Link(plate.path)
    try:
        return link.hello()
    finally:
        link.close()


def injected(plate: QemuPlate, kind: str) -> tuple[dict, dict, dict]:
    """Inject ``kind`` into a running board: its boot line after the reset, what it says happened, the silence."""
    assert next_event(plate, ("boot",))["reset_reason"] == "power-on"
    next_event(plate, ("stats",))  # a second of the board running normally: its watchdog stays quiet meanwhile
    plate.inject_fault(kind)
    assert next_event(plate, ("fault_injected",))["kind"] == kind
    boot = next_event(plate, ("boot",))
    happened = next_event(plate, ("watchdog_reset", "board_fault"))
    blanked = next_event(plate, ("output_blanked",))
    return boot, happened, blanked
