"""``ultraglide devices`` and ``ultraglide plate-sim``."""

from __future__ import annotations

import json
import signal
import threading

from ultraglide.devices.listing import list_devices
from ultraglide.devices.plate_sim import PtyPlate
from ultraglide.devices.profiles import load_profile


def list_all(args) -> int:
    found = list_devices()
    if args.json:
        print(json.dumps(found))
        return 0
    print(f"sim          {found['simulator']['description']}")
    for port in found["serial"]:
        print(f"{port['url']:12} {port['description']}")
    if not found["serial"]:
        print("(no serial ports)")
    for output in found["audio"]:
        rates = ", ".join(f"{r // 1000:g} kHz" for r in output["rates_hz"]) or "no rate that carries 20-28 kHz"
        print(f"{output['url']:12} {output['name']} ({output['hostapi']}): {rates}")
    if found["audio_error"]:
        print(f"(audio: {found['audio_error']})")
    elif not found["audio"]:
        print("(no audio outputs)")
    return 0


def plate_sim(args) -> int:
    plate = PtyPlate(load_profile(args.profile), args.link).start()
    done = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: done.set())
    print(f"simulated plate {plate.simulator.profile.name} on {plate.path} (pty {plate.pty_name}); "
          "Ctrl-C stops it", flush=True)
    try:
        while not done.wait(0.2):
            pass
    finally:
        plate.stop()
    c = plate.simulator.counters
    print(f"stopped: {c.frames_ok} frames, {c.setpoints} setpoints, {c.crc_errors} CRC errors, "
          f"{c.lost_setpoints} setpoints lost, {c.watchdog_trips} watchdog trips, peak "
          f"{plate.simulator.peak_um_pp:.2f} µm p-p")
    return 0
