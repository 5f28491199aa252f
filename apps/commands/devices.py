"""``ultraglide devices``: the outputs this machine has."""

from __future__ import annotations

import argparse
import json


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide devices``: its options."""
    devices = commands.add_parser("devices", help="list outputs: audio, serial ports, the simulator",
                                  description="Audio outputs with the sample rates they accept, serial ports "
                                              "and the simulated plate.")
    devices.add_argument("--json", action="store_true", help="print one JSON object")
    devices.set_defaults(run=run)


def run(args) -> int:
    from ultraglide.devices.listing import list_devices

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


