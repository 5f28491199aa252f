"""What the emulated board's link carries: the figure the QEMU image states in HELLO_REPLY (``link_bytes_per_s``).

Run: .venv/bin/python bench/bench_qemu_link.py [--seconds 5] [--runs 3] [--offer BYTES_PER_S] [--json]
Boots the netduinoplus2 QEMU image (``plate-sim --board qemu``'s, or ``--board mps2-an386``'s), writes HEARTBEAT
frames to its link as the engine's writer does (``FrameWriter``; paced at ``--offer`` bytes a second, or as fast as
the pseudo-terminal takes them), drains what the board sends, and reads the board's own ``rx_bytes`` counter from
its statistics lines (one a second on its debug console): bytes the firmware took, over the seconds between the
first and last line. QEMU's USART hands the firmware one byte per round trip between two of its threads, so the
figure depends on how busy the machine is: the load is printed. The image states the highest offer it was seen to
take whole (``BOARD_QEMU_LINK_BYTES_PER_S`` in ports/netduinoplus2/board.h); the host streams at most half of it.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import threading
import time

from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.boards import build_images
from ultraglide.devices.firmware.qemu import QemuPlate
from ultraglide.devices.serial.link import FrameWriter, open_port


def stats_lines(plate: QemuPlate, count: int, timeout_s: float) -> list[dict]:
    found: list[dict] = []
    deadline = time.monotonic() + timeout_s
    while len(found) < count and time.monotonic() < deadline:
        try:
            event = plate.events.get(timeout=0.2)
        except queue.Empty:
            continue
        if event["event"] == "stats":
            found.append(event)
    return found


def one_run(elf: str, seconds: int, offer: int = 0, machine: str = "netduinoplus2") -> dict:
    frame = p.encode_frame(p.HEARTBEAT, 1)
    with QemuPlate(elf, machine=machine) as plate:
        port = open_port(plate.path, 921600, write_timeout_s=2.0)
        frames = FrameWriter(port, 2.0)  # as the engine writes: the port polled only when the kernel took part
        stop = threading.Event()
        written = [0]

        def write() -> None:
            chunk = frame * (64 if not offer else 8)
            started = time.monotonic()
            while not stop.is_set():
                if offer:  # paced: ``offer`` bytes a second, not more
                    ahead = written[0] / offer - (time.monotonic() - started)
                    if ahead > 0:
                        time.sleep(ahead)
                frames.write(chunk)
                written[0] += len(chunk)

        def drain() -> None:  # the board's telemetry, read and dropped: a full pty would stall its UART
            while not stop.is_set():
                port.read(max(1, port.in_waiting))

        stats_lines(plate, 1, 30.0)  # booted and counting
        writer = threading.Thread(target=write, daemon=True)
        reader = threading.Thread(target=drain, daemon=True)
        writer.start()
        reader.start()
        try:
            lines = stats_lines(plate, seconds + 2, seconds + 30.0)[1:]  # the first second: the writer starting
        finally:
            stop.set()
            writer.join(timeout=5)
            reader.join(timeout=5)
            port.close()
    if len(lines) < 2:
        raise SystemExit(f"the board printed {len(lines)} statistics lines while the host wrote {written[0]} bytes")
    first, last = lines[0], lines[-1]
    board_s = (last["t_s"] - first["t_s"])
    taken = last["rx_bytes"] - first["rx_bytes"]
    return {"offered_bytes_per_s": offer or None,
            "bytes_per_s": round(taken / board_s), "seconds": round(board_s, 3), "rx_overflows":
            last["rx_overflows"] - first["rx_overflows"], "load_1min": os.getloadavg()[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=int, default=5)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--offer", type=int, default=0, help="bytes a second the host offers (0: as fast as the pty "
                                                                 "takes them)")
    parser.add_argument("--board", choices=["netduinoplus2", "mps2-an386"], default="netduinoplus2")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    elf = build_images(args.board, ["qemu"])[0].elf_path
    runs = [one_run(elf, args.seconds, args.offer, args.board) for _ in range(args.runs)]
    if args.json:
        print(json.dumps({"runs": runs, "lowest_bytes_per_s": min(r["bytes_per_s"] for r in runs)}))
        return
    for run in runs:
        offered = f"offered {run['offered_bytes_per_s']}, taken " if run["offered_bytes_per_s"] else ""
        print(f"{offered}{run['bytes_per_s']} bytes/s over {run['seconds']:g} s of the board's time "
              f"(rx overflows {run['rx_overflows']}; load average {run['load_1min']:.1f})")
    print(f"lowest: {min(r['bytes_per_s'] for r in runs)} bytes/s")


if __name__ == "__main__":
    main()
