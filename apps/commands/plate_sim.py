"""``ultraglide plate-sim``: the simulated plate driver on a pseudo-terminal, one line per event."""

from __future__ import annotations

import argparse
import queue
import time

from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.output import print_json, print_line
from ultraglide.apps.cli.signals import held
from ultraglide.apps.cli.types import CARRIER_HZ, CLOCK_PPM, DRIFT_HZ_PER_S, Q_FACTOR
from ultraglide.apps.commands.finger_options import add_finger_options, finger_asked, finger_config


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide plate-sim``: its options."""
    sim = commands.add_parser("plate-sim", help="serve the simulated plate on a pseudo-terminal",
                              description="Run the simulated plate driver on a pty and print its path; "
                                          "connect with --device serial:PATH. Prints one line per event "
                                          "(connected, enabled, carrier, stream started/stopped, fault, "
                                          "watchdog, disabled, disconnected) with its time. Runs until stopped.")
    sim.add_argument("--profile", default="sim-plate",
                     help="the simulated plate's profile, or rig:RIG.toml for a rig's plate (default: sim-plate)")
    output_option(sim, "--link", kind="link", metavar="PATH", help="serve at this path (default: a new temporary one)")
    sim.add_argument("--resonance-hz", type=CARRIER_HZ, metavar="F",
                     help="the simulated plate's real resonance, Hz (default: the profile's)")
    sim.add_argument("--q", type=Q_FACTOR, metavar="Q", help="its real quality factor (default: the profile's)")
    sim.add_argument("--drift-hz-per-s", type=DRIFT_HZ_PER_S, default=0.0, metavar="D",
                     help="its resonance drifts by D Hz every second (default: 0)")
    sim.add_argument("--clock-ppm", type=CLOCK_PPM, default=0.0, metavar="PPM",
                     help="its crystal runs PPM parts per million fast (negative: slow) against the host's clock, "
                          "so it plays setpoints faster (slower) than they come, as a real board's may "
                          "(default: 0)")
    sim.add_argument("--json", action="store_true", help="print each event as a line of JSON")
    sim.add_argument("--max-version", choices=["2", "3"], default="3", metavar="V",
                     help="the highest protocol version the simulated firmware speaks: 3, or 2 to test a host's "
                          "v2 path (default: 3)")
    sim.add_argument("--break", dest="breaks", action="append", default=[], metavar="RULE",
                     help="break one rule of docs/protocol.md on purpose (R-NAK-ORDER, R-WATCHDOG, ...; see its "
                          "Conformance section), to test `plate check`; repeat for several")
    sim.add_argument("--lie", dest="lies", action="append", default=[], metavar="FRAME.FIELD=VALUE",
                     help="report VALUE for a field of HELLO_REPLY, TELEMETRY or SENSORS (hello.watchdog_ms=5, "
                          "telemetry.measured_um_pp=0.2: a plate that ignores the amplitude; sensors.normal_force_n="
                          "nan ...), to test what a host believes; repeat for several")
    sim.add_argument("--board", choices=["sim", "qemu", "netduinoplus2", "mps2-an386"], default="sim",
                     help="sim: the firmware's core on this machine; qemu (or netduinoplus2): the netduinoplus2 "
                          "board image under QEMU; mps2-an386: the mps2-an386 board image under QEMU (built first "
                          "if needed), its link UART on the pty (default: sim)")
    sim.add_argument("--board-fault", type=board_fault, metavar="KIND@SECONDS",
                     help="a board only: make the board fail SECONDS after it serves, KIND one of "
                          "isr-hang (its block interrupt stops), main-hang (its main loop stops), stack-overflow, "
                          "hard-fault; its watchdog or fault handler silences the output and resets it, and the "
                          "events say so (watchdog_reset or board_fault, output_blanked with after_fault_ms)")
    add_finger_options(sim, "the force sensors under the plate; absent unless a --finger option is given")
    sim.set_defaults(run=run)


def board_fault(text: str) -> tuple[str, float]:
    """``KIND@SECONDS`` (``isr-hang@2``) as (kind, seconds); argparse's error otherwise."""
    from ultraglide.devices.firmware.qemu import FAULT_KINDS

    kind, at, seconds = text.partition("@")
    if kind not in FAULT_KINDS or not at:
        raise argparse.ArgumentTypeError(f"must be KIND@SECONDS with KIND one of {', '.join(FAULT_KINDS)}, got {text}")
    try:
        value = float(seconds)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{seconds!r} is not a number of seconds") from None
    if not 0.0 <= value <= 86_400.0:
        raise argparse.ArgumentTypeError(f"the fault's time must lie within 0-86400 s, got {seconds}")
    return kind, value


def _rules(texts: list[str]) -> tuple[str, ...]:
    """Rule identifiers the simulated firmware can break (R-NAK-ORDER, or nak-order); UsageError otherwise."""
    from ultraglide.apps.cli.errors import UsageError
    from ultraglide.devices.firmware.sil import rules

    known = rules()
    found = []
    for text in texts:
        rule = text.upper() if text.upper().startswith("R-") else f"R-{text.upper()}"
        if rule not in known:
            raise UsageError(f"no rule {text!r} to break; the simulator can break {', '.join(known)}")
        found.append(rule)
    return tuple(found)


def describe_event(event: dict) -> str:
    """One event of the simulated plate as a line for people: its time, what happened, the details."""
    fields = {key: value for key, value in event.items() if key not in ("t_s", "event")}
    if event["event"] == "watchdog":
        fields.pop("fault", None)  # the event's name says it
    def words(value) -> str:
        return " and ".join(map(str, value)) if isinstance(value, list) else str(value)

    details = ", ".join(words(value) if key == "fault" else f"{key} {words(value)}" for key, value in fields.items())
    return f"{event['t_s']:10.3f} s  {event['event']}{'  ' + details if details else ''}"


def run(args) -> int:
    args.max_version = int(args.max_version)
    args.breaks = list(_rules(args.breaks))
    if args.board == "sim" and args.board_fault:
        from ultraglide.apps.cli.errors import UsageError

        raise UsageError("--board-fault is a board's (--board qemu or mps2-an386): the simulator's faults come "
                         "from the host (SIM_FAULT)")
    if args.board in ("qemu", "netduinoplus2", "mps2-an386"):
        if args.breaks or args.max_version != 3 or finger_asked(args) or args.clock_ppm or args.lies:
            from ultraglide.apps.cli.errors import UsageError

            raise UsageError("--break, --lie, --max-version, --clock-ppm and --finger are the simulator's "
                             "(--board sim), not the board image's (it keeps QEMU's clock)")
        return _plate_sim_qemu(args)
    from ultraglide.devices.rig import load_plate
    from ultraglide.devices.sim.lies import Lies
    from ultraglide.devices.sim.plate import PlateTruth
    from ultraglide.devices.sim.pty_plate import PtyPlate
    from ultraglide.render.engine.finger_setup import build_finger, finger_words
    from ultraglide.render.engine.realtime import threads_started_in_real_time

    lies = Lies.parse(args.lies)  # (a DeviceError in one line for a field that is not there)
    profile = load_plate(args.profile)
    truth = PlateTruth(args.resonance_hz or profile.resonance_hz, args.q or profile.q, args.drift_hz_per_s,
                       clock_ppm=args.clock_ppm)
    config = finger_config(args)
    finger = build_finger(config) if config is not None else None
    try:
        # its threads keep the plate's time as a board's timer does: in real time where the machine allows, so that
        # a loaded machine does not starve the simulated plate (its clock's drift once went unseen by the host, the
        # plate's own lag cancelling it); what starts them stays ordinary
        with threads_started_in_real_time():
            plate = PtyPlate(profile, args.link, truth, breaks=tuple(args.breaks), max_version=args.max_version,
                             finger=finger, lies=lies).start()
    except BaseException:
        if finger is not None:
            finger.close()
        raise
    sim = plate.simulator

    def show(event: dict) -> None:
        print_json(event) if args.json else print_line(describe_event(event))

    try:  # whatever ends the loop (a signal turned exception included), the pty and its link go
        if args.json:
            show({"t_s": 0.0, "event": "serving", "path": plate.path, "pty": plate.pty_name,
                  "profile": profile.name, "resonance_hz": truth.resonance_hz, "q": truth.q,
                  "drift_hz_per_s": truth.drift_hz_per_s, "clock_ppm": truth.clock_ppm,
                  "max_version": args.max_version, "breaks": args.breaks, "lies": args.lies,
                  "finger": None if config is None else finger_words(config)})
        else:
            broken = f"; breaking {', '.join(args.breaks)} on purpose" if args.breaks else ""
            broken += f"; lying: {', '.join(args.lies)}" if args.lies else ""
            version = "" if args.max_version == 3 else f"; speaking protocol v{args.max_version} at most"
            clock = f"; its clock {truth.clock_ppm:+g} ppm" if truth.clock_ppm else ""
            print_line(f"simulated plate {profile.name} on {plate.path} (pty {plate.pty_name}); resonance "
                       f"{truth.resonance_hz:g} Hz, Q {truth.q:g}, drift {truth.drift_hz_per_s:g} Hz/s"
                       f"{clock}{version}{broken}; Ctrl-C stops it")
            if config is not None:
                print_line(finger_words(config))
        while True:  # until a stop signal (Ctrl-C, SIGTERM, SIGHUP) raises through here
            try:
                show(sim.events.get(timeout=0.1))
            except queue.Empty:
                continue
    finally:
        with held():  # a second signal does not cut this short
            plate.stop()
            if finger is not None:
                finger.close()  # its log appears whole
            for _ in range(sim.events.qsize()):  # what is there: a thread that outlived its stop and kept adding
                show(sim.events.get_nowait())  # events must not keep the command from ending
            _summary(sim, args.json, show)


def _summary(sim, as_json: bool, show) -> None:
    c = sim.counters
    faults = {name: count for name, count in sim.fault_counts().items() if count}
    if as_json:
        show({"t_s": round(sim.elapsed_s(), 4), "event": "stopped", "frames": c.frames_ok, "setpoints": c.setpoints,
              "crc_errors": c.crc_errors, "lost_setpoints": c.lost_setpoints, "late_setpoints": c.late_setpoints,
              "overrun_setpoints": c.overrun_setpoints, "discarded_setpoints": c.discarded_setpoints,
              "watchdog_trips": c.watchdog_trips, "faults": sim.fault_counts(), "peak_um_pp": round(sim.peak_um_pp, 4)})
    else:
        fault_words = ", ".join(f"{count} {name}" for name, count in faults.items()) or "none"
        print_line(f"stopped: {c.frames_ok} frames, {c.setpoints} setpoints, {c.crc_errors} CRC errors, "
              f"{c.lost_setpoints} setpoints lost, {c.late_setpoints} late, {c.watchdog_trips} watchdog trips, "
              f"faults: {fault_words}, peak {sim.peak_um_pp:.2f} µm p-p")


def _plate_sim_qemu(args) -> int:
    """A board's image under QEMU (``--board qemu`` is the netduinoplus2's), its link UART on a pty; the board's
    debug console gives the events."""
    from ultraglide.devices.errors import DeviceError
    from ultraglide.devices.firmware.boards import BOARD_INFO, build_images
    from ultraglide.devices.firmware.qemu import EmulatedPlate, QemuPlate
    from ultraglide.devices.rig import load_plate

    board = BOARD_INFO["netduinoplus2" if args.board == "qemu" else args.board]
    profile = load_plate(args.profile)
    truth = EmulatedPlate.of(profile, args.resonance_hz, args.q, args.drift_hz_per_s)
    image = build_images(board.name, ["qemu"])[0]
    plate = QemuPlate(image.elf_path, args.link, plate=truth, machine=board.machine)

    def show(event: dict) -> None:
        print_json(event) if args.json else print_line(describe_event(event))

    last: dict = {}
    plate.start()
    try:
        if args.json:
            show({"t_s": 0.0, "event": "serving", "path": plate.path, "pty": plate.pty_name, "board": board.name,
                  "image": image.elf_path, "profile": profile.name, "resonance_hz": truth.resonance_hz,
                  "q": truth.q, "drift_hz_per_s": truth.drift_hz_per_s})
        else:
            print_line(f"{board.name} image under QEMU, plate {profile.name} on {plate.path} (pty {plate.pty_name}); "
                  f"resonance {truth.resonance_hz:g} Hz, Q {truth.q:g}, drift {truth.drift_hz_per_s:g} Hz/s; "
                  "Ctrl-C stops it")
        fault_at = time.monotonic() + args.board_fault[1] if args.board_fault else None
        while True:  # until a stop signal raises through here, or QEMU dies
            if fault_at is not None and time.monotonic() >= fault_at:
                plate.inject_fault(args.board_fault[0])
                fault_at = None
            try:
                event = plate.events.get(timeout=0.01 if fault_at is not None else 0.1)
            except queue.Empty:
                if not plate.alive:
                    raise DeviceError(f"QEMU stopped unexpectedly (exit status {plate.process.returncode})")  # noqa: B904
                continue
            if event["event"] == "stats":
                last = event
            else:
                show(event)
    finally:
        with held():
            last = _final_stats(plate, last, show)
            plate.stop()
            while not plate.events.empty():
                event = plate.events.get()
                if event["event"] == "stats":
                    last = event
                else:
                    show(event)
            _qemu_summary(last, plate.elapsed_s(), args.json, show)


def _final_stats(plate, last: dict, show, timeout_s: float = 3.0) -> dict:
    """The board's next statistics line (one a second on its clock), so that the closing line counts what it
    received up to the stop; the last one seen if QEMU is gone or stalled past ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while plate.alive and time.monotonic() < deadline:
        try:
            event = plate.events.get(timeout=0.1)
        except queue.Empty:
            continue
        if event["event"] == "stats":
            return event
        show(event)
    return last


def _qemu_summary(stats: dict, elapsed_s: float, as_json: bool, show) -> None:
    """The board's last statistics line (it prints one every second) as plate-sim's closing line."""
    fields = {key: value for key, value in stats.items() if key not in ("t_s", "event")}
    if as_json:
        show({"t_s": round(elapsed_s, 4), "event": "stopped", **fields})
        return
    if not fields:
        print_line("stopped: no statistics from the board yet")
        return
    count = lambda key: fields.get(key, 0)  # noqa: E731
    print_line(f"stopped: {count('frames')} frames, {count('setpoints')} setpoints, {count('crc_errors')} CRC errors, "
          f"{count('lost_setpoints')} setpoints lost, {count('late_setpoints')} late, "
          f"{count('watchdog_trips')} watchdog trips, {count('underruns')} underruns, {count('trips')} trips; "
          f"peak {count('peak_um_pp'):.2f} µm p-p "
          f"measured (the plate's own {count('plate_peak_um_pp'):.2f}); highest setpoint received "
          f"{count('max_setpoint_code')} of 65535 (the limit's code {count('limit_code')}); QEMU stalled "
          f"{count('skipped_ms')} ms")
