"""How far behind the QEMU boards' CLOCK replies are: each reply's place within its block against the board's own
clock (issue 43).

Run: .venv/bin/python bench/bench_board_clock.py [--board netduinoplus2|mps2-an386] [--requests 300] [--json]
Boots the board's QEMU image, says HELLO (v3) and asks CLOCK ``--requests`` times, one at a time, each after a
random pause of 0-3 ms (so the requests fall anywhere in the board's 1 ms blocks). For each, the board's debug
console tells the raw reading its port took to answer (``ev clock_read``: its free-running clock's count and the
count at which the next block falls due), from which this script works out by hand how many drive samples
(48 kHz) of the block the ADC had taken when the request was answered. The reply is behind by those samples less
the ones it states (its fraction, in 1/65536 of a 1 kHz sensor sample, 48 drive samples). Before issue 43's
port change the boards stated none (``ug_port_samples_since_block`` returned 0), so their replies were behind by
all of them: "before" below is that, from the same readings. A block that fell due but had not run yet when the
request was answered (the block interrupt late) is counted too; the port can state at most 47 of its samples.
The machine's load is printed.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import random
import threading
import time
import tty

import numpy as np
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware.boards import BOARD_INFO, build_images
from ultraglide.devices.firmware.qemu import QemuPlate

DRIVE_RATE_HZ = 48_000  # ports/*/board.h BOARD_DRIVE_RATE_HZ
SENSOR_RATE_HZ = 1_000  # HELLO_REPLY's sensor_rate_hz on both boards
BLOCK_SAMPLES = DRIVE_RATE_HZ // 1000  # one block is one millisecond
# the free-running clock each QEMU image runs its blocks by: counts a millisecond (one block)
TICKS_PER_BLOCK = {"netduinoplus2": 1_000_000,  # TIM5 counting QEMU's virtual nanoseconds
                   "mps2-an386": 25_000}  # TIMER1 counting the 25 MHz PCLK


def taken_samples(read: dict, board: str) -> int:
    """Drive samples of the block the ADC had taken at a ``clock_read``: the board clock's count past the end of
    the block last run (``due`` is when the next one falls due), worked out here from the raw counts; more than a
    block when one fell due and had not run."""
    per_block = TICKS_PER_BLOCK[board]
    elapsed = (read["ticks"] - (read["due"] - per_block)) % 2**32
    return elapsed * BLOCK_SAMPLES // per_block


def stated_samples(reply: p.ClockReply) -> int:
    """Drive samples past the sensor sample a reply states (its fraction, 48 drive samples a sensor sample)."""
    return round(reply.fraction * (DRIVE_RATE_HZ // SENSOR_RATE_HZ) / 65536)


class Replies:
    """The board's link read on a thread: its CLOCK_REPLY frames, in order."""

    def __init__(self, fd: int):
        self.fd = fd
        self.frames: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        import select

        decoder = p.FrameDecoder()
        while not self._stop.is_set():
            if select.select([self.fd], [], [], 0.05)[0]:
                try:
                    data = os.read(self.fd, 4096)
                except OSError:
                    return
                for frame in decoder.feed(data):
                    if frame.kind in (p.HELLO_REPLY, p.CLOCK_REPLY):
                        self.frames.put(frame)

    def next(self, kind: int, timeout_s: float = 20.0) -> p.Frame:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with contextlib.suppress(queue.Empty):
                frame = self.frames.get(timeout=0.1)
                if frame.kind == kind:
                    return frame
        raise TimeoutError(f"no frame of kind {kind:#x} within {timeout_s} s")

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


def next_clock_read(plate: QemuPlate, after: int, timeout_s: float = 20.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with contextlib.suppress(queue.Empty):
            event = plate.clock_reads.get(timeout=0.1)
            if event["reads"] > after:
                return event
    raise TimeoutError(f"no clock_read event within {timeout_s} s")


def measure(board: str, requests: int, seed: int = 43) -> list[tuple[dict, p.ClockReply]]:
    """(the board's reading, the reply) for each of ``requests`` CLOCK requests at random times."""
    image = build_images(board, ["qemu"])[0]
    pauses = random.Random(seed)
    found: list[tuple[dict, p.ClockReply]] = []
    with QemuPlate(image.elf_path, machine=BOARD_INFO[board].machine) as plate:
        fd = os.open(plate.path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        replies = Replies(fd)
        try:
            seq = 0
            for _ in range(60):  # QEMU's pty passes bytes about a second after it is opened
                seq += 1
                os.write(fd, p.encode_frame(p.HELLO, seq, p.hello_payload(3)))
                with contextlib.suppress(TimeoutError):
                    replies.next(p.HELLO_REPLY, timeout_s=1.0)
                    break
            reads = 0
            for _ in range(requests):
                threading.Event().wait(pauses.uniform(0.0, 0.003))  # a random phase within the block, no condition
                seq = (seq + 1) & 0xFFFF
                os.write(fd, p.encode_frame(p.CLOCK, seq, b""))
                reply = p.parse_clock_reply(replies.next(p.CLOCK_REPLY).payload)
                assert reply.asked_seq == seq
                read = next_clock_read(plate, reads)
                reads = read["reads"]
                found.append((read, reply))
        finally:
            replies.stop()
            os.close(fd)
    return found


def summary(board: str, found: list[tuple[dict, p.ClockReply]]) -> dict:
    taken = np.array([taken_samples(read, board) for read, _ in found])
    stated = np.array([stated_samples(reply) for _, reply in found])
    to_us = 1e6 / DRIVE_RATE_HZ

    def figures(behind: np.ndarray) -> dict:
        return {"median_us": round(float(np.median(behind)) * to_us, 1),
                "p95_us": round(float(np.percentile(behind, 95)) * to_us, 1),
                "max_us": round(float(behind.max()) * to_us, 1)}

    return {"board": board, "requests": len(found), "before": figures(taken), "after": figures(taken - stated),
            "due_not_run": int(np.sum(taken >= BLOCK_SAMPLES)), "load": os.getloadavg()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--board", choices=sorted(TICKS_PER_BLOCK), default="netduinoplus2")
    parser.add_argument("--requests", type=int, default=300)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = summary(args.board, measure(args.board, args.requests))
    if args.json:
        print(json.dumps(result))
        return
    print(f"{result['board']}: {result['requests']} CLOCK requests, load {result['load'][0]:.1f}")
    for when in ("before", "after"):
        f = result[when]
        print(f"  {when:6s} behind the board's clock: median {f['median_us']} us, p95 {f['p95_us']} us, "
              f"max {f['max_us']} us")
    print(f"  answered with a block due and not yet run: {result['due_not_run']}")


if __name__ == "__main__":
    main()
