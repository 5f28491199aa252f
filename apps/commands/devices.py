"""``ultraglide devices``: the outputs this machine has."""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.output import print_json


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide devices``: its options."""
    devices = commands.add_parser("devices", help="list outputs: audio, serial ports, the simulator",
                                  description="Audio outputs with the sample rates they accept, serial ports "
                                              "and the simulated plate.")
    devices.add_argument("--json", action="store_true", help="print one JSON object")
    devices.set_defaults(run=run)


def run(args) -> int:
    from ultraglide.devices.sinks.listing import list_devices

    found = list_devices()
    if args.json:
        print_json(found)
        return 0
    rows = [("sim", found["simulator"]["description"])]
    rows += [(port["url"], port_words(port)) for port in found["serial"]]
    for output in found["audio"]:
        rates = ", ".join(f"{r // 1000:g} kHz" for r in output["rates_hz"]) or "no rate that carries 20-28 kHz"
        rows.append((output["url"], f"{output['name']} ({output['hostapi']}): {rates}"))
    width = max(len(url) for url, _ in rows)
    for url, words in rows:
        print(f"{url:{width}}  {words}")
    if not found["serial"]:
        print("(no serial ports)")
    if found["audio_error"]:
        print(f"(audio: {found['audio_error']})")
    elif not found["audio"]:
        print("(no audio outputs)")
    return 0




def port_words(port: dict) -> str:
    """What is known of a serial port: a USB adapter's or board's own description, or, for a port with no
    device description (pyserial's "n/a": a UART of the machine itself), that and nothing more."""
    description = port.get("description")
    if description and description != "n/a":
        hwid = port.get("hwid")
        return f"{description} ({hwid})" if hwid and hwid != "n/a" else description
    return "a serial port of this machine with nothing identified on it (not USB); a plate driver may be wired to it"
