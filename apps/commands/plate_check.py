"""``ultraglide plate check``: a plate driver exercised against docs/protocol.md, one line per rule.

The rules and their checks are :mod:`ultraglide.devices.conformance.check`'s; this command opens the device (a serial
port, or ``sim``: the simulated plate on a pty of this process), prints each verdict as it is known, and exits
0 when no rule failed, 6 when one did (4 when the device was lost before the check could finish).
"""

from __future__ import annotations

import argparse
import sys

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.signals import held
from ultraglide.apps.commands.plate_choice import add_plate_options, plate_of


def add_check_parser(actions: argparse._SubParsersAction) -> None:
    """``ultraglide plate check`` and its options (an action of ``plate``)."""
    check = actions.add_parser(
        "check", help="check a plate driver against the protocol, rule by rule",
        description="Exercise a plate driver against docs/protocol.md: each rule of its Conformance section "
                    "(handshake and version, framing and CRC, every NAK reason and their order, ENABLE, the jitter "
                    "buffer and prefill, late and lost accounting, the watchdog's timing, fault latching and "
                    "clearing, the limits, telemetry and sensors) is exercised on purpose and printed on one line: "
                    "its identifier, pass, fail or not checked, its section of docs/protocol.md, and what was seen. "
                    "The plate is driven at 15 %% of the smaller of its driver's and the profile's limit at most; "
                    "asking for more than the limit (the driver's own limiter) happens only at the carrier "
                    "farthest from resonance, where the plate moves less. Exit status 0 when no rule failed, 6 when "
                    "one did, 4 when the device was lost.")
    check.add_argument("--device", metavar="URL",
                       help="serial:PORT[?baud=N] (a plate driver; needs --rig or --profile), or sim: the simulated "
                            "plate (default: the rig's device, else sim)")
    add_plate_options(check, check, device_default="sim", profile_help="the plate's profile: its Q and limit")
    check.add_argument("--over-limit", action="store_true",
                       help="also check over-limit and the trip, which need the plate driven at its limit (on a "
                            "plate that can take 1 %% over its limit for a moment)")
    check.add_argument("--rule", dest="rules", action="append", default=[], metavar="RULE",
                       help="check only this rule (R-WATCHDOG, or watchdog; repeat for several; default: all)")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.set_defaults(run=run_check)


def _rules(names: list[str]) -> tuple[str, ...]:
    """Rule identifiers as docs/protocol.md spells them (R-WATCHDOG from watchdog too); UsageError otherwise."""
    from ultraglide.devices.conformance.check import RULES

    rules = []
    for name in names:
        rule = name.upper() if name.upper().startswith("R-") else "R-" + name.upper()
        if rule not in RULES:
            raise UsageError(f"--rule {name}: no such rule; the rules are {', '.join(RULES)}")
        rules.append(rule)
    return tuple(dict.fromkeys(rules))


def run_check(args) -> int:
    from ultraglide.devices.conformance.check import check_device
    from ultraglide.devices.urls import parse_device_url

    only = _rules(args.rules)
    profile = plate_of(args)
    device = parse_device_url(args.device)
    if device.kind not in ("sim", "serial"):
        raise UsageError(f"{device.kind} speaks no protocol: check a plate driver (sim or serial:PORT[?baud=N])")
    say = None if args.json else (lambda verdict: print(verdict.line(), flush=True))
    plate = None
    if device.kind == "sim":
        from ultraglide.devices.sim.pty_plate import PtyPlate

        plate = PtyPlate(profile).start()
        port, baudrate = plate.path, 921600
    else:
        port, baudrate = device.target, int(device.options.get("baud", 921600))
    try:  # a stop signal leaves through here: the check rests the plate on its way out
        report = check_device(port, profile, baudrate, over_limit=args.over_limit, say=say,
                              heading=None if args.json else (lambda line: print(line, flush=True)), hold=held,
                              only=only)
    finally:
        if plate is not None:
            with held():
                plate.stop()
    if args.json:
        print_json({"device_url": args.device, "profile": profile.name, **report.as_dict(),
                    "exit_status": report.exit_status})
    else:
        print(report.summary())
        if report.exit_status:
            print(f"ultraglide plate check: {report.verdict}", file=sys.stderr)
    return report.exit_status
