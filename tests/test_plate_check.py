"""``ultraglide plate check`` against the simulated plate: every rule passes on the reference firmware, each
rule the firmware breaks on purpose (``plate-sim --break RULE``) is reported as that rule failing, the plate
never moves above 15 % of its limit, and the output is one line per rule (or strict JSON) with a status
that says whether any rule failed."""

import json
import math
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli, wait_for
from test_plate_sim_cli import Server
from ultraglide.devices.conformance import check as c
from ultraglide.devices.firmware import sil
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.plate import PlateTruth
from ultraglide.devices.sim.pty_plate import PtyPlate

PROFILE = load_profile("sim-plate")  # full scale 8, limit 6 µm p-p
DOC = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")
NEEDS_THE_PLATE_OVER_ITS_LIMIT = {"R-OVER-LIMIT", "R-TRIP"}
LINE = re.compile(r"^(R-[A-Z-]+) +(pass|fail|not checked) +(.+?): (.+)$")


def strict_json(text):
    def refuse(constant):
        raise AssertionError(f"not strict JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def conformance_table() -> dict[str, str]:
    """rule → section, from docs/protocol.md's Conformance table."""
    start = DOC.index("| rule | section | what the device must do | the simulator's break |")
    rows = {}
    for line in DOC[start:].splitlines()[2:]:
        if not line.startswith("| R-"):
            break
        rule, section = (cell.strip() for cell in line.strip("|").split("|")[:2])
        rows[rule] = section
    return rows


def serve(tmp_path, *options):
    """``plate-sim`` in its own process, serving at ``tmp_path/plate`` once it says so."""
    link = tmp_path / "plate"
    server = Server("--link", link, "--json", *options)
    server.wait_line(lambda line: '"serving"' in line)
    return server, str(link)


def test_the_checks_rules_are_the_documents():
    assert c.RULES == conformance_table()  # every rule of the page, in its section, and no other


@pytest.mark.slow
def test_plate_check_passes_on_the_simulated_plate_one_line_a_rule():
    result = run_cli("plate", "check", "--device", "sim", timeout=240)
    assert result.returncode == 0, result.stdout + result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("checking 'ultraglide plate simulator' on ") and "protocol v3" in lines[0]
    assert "driving at most 0.90 µm p-p (15 % of the plate driver's 6 µm p-p limit) at 25000 Hz" in lines[0]
    verdicts = [LINE.match(line) for line in lines[1:-1]]
    assert all(verdicts), lines
    seen = {m.group(1): (m.group(2), m.group(3), m.group(4)) for m in verdicts}
    table = conformance_table()
    assert len(verdicts) == len(seen) == len(table)  # each rule once
    for rule, (outcome, section, words) in seen.items():
        assert section == table[rule] and words
        assert outcome == ("not checked" if rule in NEEDS_THE_PLATE_OVER_ITS_LIMIT else "pass"), (rule, words)
    assert re.fullmatch(r"28 rules pass, 0 fail, 2 not checked \(\d+\.\d s\)", lines[-1])
    assert result.stderr == ""


@pytest.mark.slow
def test_a_full_check_names_the_one_rule_broken_in_strict_json_and_never_moves_the_plate_past_15_percent(tmp_path):
    """A separate plate-sim breaking R-NAK-ORDER: the check exits 6 naming that rule and no other, its JSON is
    strict, and the simulated plate's own peak over the whole check stays within 15 % of its 6 µm p-p limit."""
    server, link = serve(tmp_path, "--break", "R-NAK-ORDER")
    try:
        result = run_cli("plate", "check", "--device", f"serial:{link}", "--profile", "sim-plate",
                         "--json", timeout=240)
    finally:
        assert server.finish(signal.SIGTERM) == 128 + signal.SIGTERM, server.err
    assert result.returncode == 6, result.stdout + result.stderr
    report = strict_json(result.stdout)
    assert report["broken_rules"] == ["R-NAK-ORDER"] and report["failed"] == 1 and report["exit_status"] == 6
    assert sorted(rule["rule"] for rule in report["rules"]) == sorted(conformance_table())  # each rule once
    broken = next(rule for rule in report["rules"] if rule["rule"] == "R-NAK-ORDER")
    assert broken["verdict"] == "fail" and broken["section"] == "Host → device"
    assert "NAK 3, not NAK 2" in broken["seen"]  # what it saw: a value checked before the length
    assert report["device"]["max_amplitude_um_pp"] == 6.0 and report["aborted"] is None
    stopped = strict_json(server.seen[-1])
    assert stopped["event"] == "stopped"
    assert stopped["peak_um_pp"] <= 0.15 * 6.0 * 1.001  # never above 15 % of the limit, on the plate itself
    assert stopped["peak_um_pp"] > 0.8  # and it was driven: 0.9 µm p-p at resonance
    assert result.stderr == ""  # --json: the one object says it all


BREAKABLE = [rule for rule in sil.rules() if rule not in NEEDS_THE_PLATE_OVER_ITS_LIMIT]


@pytest.mark.slow
@pytest.mark.parametrize("rule", BREAKABLE)
def test_each_rule_broken_on_purpose_is_reported_as_that_rule_failing(rule):
    # the simulated plate in this process, on its own pty (plate-sim --break is the same simulator: its
    # command line is checked once, above)
    plate = PtyPlate(PROFILE, breaks=(rule,)).start()
    try:
        report = c.check_device(plate.path, PROFILE, only=(rule,))
    finally:
        plate.stop()
    (verdict,) = report.verdicts
    assert (verdict.rule, verdict.outcome) == (rule, c.FAIL), verdict.line()
    assert report.exit_status == 6 and report.failed == (rule,)


def stronger_plate(breaks=(), full_scale_um_pp=8.04):
    """The simulated plate 0.5 % stronger than its driver believes: driven at its limit, it goes 0.5 % over
    (over-limit, not the trip's 1 %); at 8.2 it goes 2.5 % over."""
    truth = PlateTruth(PROFILE.resonance_hz, PROFILE.q, full_scale_um_pp=full_scale_um_pp)
    return PtyPlate(PROFILE, truth=truth, breaks=breaks).start()


@pytest.mark.slow
@pytest.mark.parametrize("breaks, full_scale, outcomes", [
    ((), 8.04, {"R-OVER-LIMIT": c.PASS, "R-TRIP": c.NOT_CHECKED}),
    (("R-OVER-LIMIT",), 8.04, {"R-OVER-LIMIT": c.FAIL, "R-TRIP": c.NOT_CHECKED}),
    ((), 8.2, {"R-OVER-LIMIT": c.PASS, "R-TRIP": c.PASS}),
    ((), 8.0, {"R-OVER-LIMIT": c.NOT_CHECKED, "R-TRIP": c.NOT_CHECKED}),  # it never goes over: nothing to see
])
def test_over_limit_and_the_trip_are_checked_only_when_asked_on_a_plate_that_goes_over(breaks, full_scale, outcomes):
    plate = stronger_plate(breaks, full_scale)
    try:
        asked = c.check_device(plate.path, PROFILE, over_limit=True, only=tuple(outcomes))
        unasked = c.check_device(plate.path, PROFILE, only=tuple(outcomes))
        peak = plate.simulator.peak_um_pp
    finally:
        plate.stop()
    assert {v.rule: v.outcome for v in asked.verdicts} == outcomes, [v.line() for v in asked.verdicts]
    assert {v.outcome for v in unasked.verdicts} == {c.NOT_CHECKED}
    assert all("--over-limit" in v.seen for v in unasked.verdicts)
    assert peak <= 6.0 * 1.03  # at its limit, and the trip cut what went 1 % over
    assert asked.aborted is None


@pytest.mark.slow
def test_a_v2_device_passes_what_v2_can_show():
    plate = PtyPlate(PROFILE, max_version=2).start()  # as plate-sim --max-version 2 serves it
    try:
        report = c.check_device(plate.path, PROFILE)
    finally:
        plate.stop()
    outcomes = {v.rule: v.outcome for v in report.verdicts}
    assert c.FAIL not in outcomes.values(), [v.line() for v in report.verdicts]
    v3_only = {"R-ENABLE", "R-PREFILL", "R-HELLO-NO-STATE", "R-SCALING", "R-LIMIT", "R-SENSORS"}
    assert {rule for rule, outcome in outcomes.items() if outcome == c.NOT_CHECKED} == \
        v3_only | NEEDS_THE_PLATE_OVER_ITS_LIMIT
    assert report.device.version == 2 and report.exit_status == 0


def written_from_v2_alone(plate: PtyPlate) -> PtyPlate:
    """The simulated plate held to v2 as a driver written from the v2 protocol alone would be: v3's types
    (SET_LOOP 0x07, SETPOINTS_FORCE 0x08) are not in its table, so its parser meets them as any unknown type
    (0x42 here, its CRC made anew) and answers NAK 1, where a v3 core held to v2 knows them and answers NAK 4."""
    from ultraglide.devices import protocol as p

    return not_in_its_table(plate, p.V3_COMMANDS)


def not_in_its_table(plate: PtyPlate, kinds) -> PtyPlate:
    """The simulated plate with the command types ``kinds`` missing from its parser's table: it meets them as any
    unknown type (0x42 here, its CRC made anew) and answers NAK 1."""
    from ultraglide.devices import protocol as p

    receive, pending = plate.simulator.receive, bytearray()

    def receive_as_v2(data: bytes) -> list[bytes]:
        pending.extend(data)
        *whole, rest = bytes(pending).split(b"\x00")
        pending[:] = rest
        out = bytearray()
        for packet in whole:
            try:
                frame = p.decode_frame(packet)
            except p.ProtocolError:  # not a frame of ours: the core counts it as it comes
                out += packet + b"\x00"
                continue
            kind = 0x42 if frame.kind in kinds else frame.kind
            out += p.encode_frame(kind, frame.seq, frame.payload) if kind != frame.kind else packet + b"\x00"
        return receive(bytes(out)) if out else []

    plate.simulator.receive = receive_as_v2
    return plate


@pytest.mark.slow
def test_a_device_written_from_v2_alone_passes_by_its_version():
    """A v2-only driver answers v3's SET_LOOP and SETPOINTS_FORCE with NAK 1 (unknown type), as v2 asks: judged by
    its version, R-NAK-ORDER, R-LOOP and R-FORCE pass (they failed, expecting v3's NAK 4)."""
    plate = written_from_v2_alone(PtyPlate(PROFILE, max_version=2)).start()
    try:
        probe = c.Probe(plate.path)
        try:
            probe.hello(2)
            answer = probe.command(0x07, b"\x01")  # what the device itself answers, before the check judges it
        finally:
            probe.close()
        report = c.check_device(plate.path, PROFILE, only=("R-NAK-ORDER", "R-LOOP", "R-FORCE", "R-NAK-NO-EFFECT",
                                                            "R-VERSION"))
    finally:
        plate.stop()
    assert answer[:2] == ("nak", 1)
    outcomes = {v.rule: v.outcome for v in report.verdicts}
    assert outcomes == {"R-NAK-ORDER": c.PASS, "R-LOOP": c.PASS, "R-FORCE": c.PASS, "R-NAK-NO-EFFECT": c.PASS,
                        "R-VERSION": c.PASS}, [v.line() for v in report.verdicts]
    seen = {v.rule: v.seen for v in report.verdicts}
    assert "NAK 1 for SET_LOOP of 2 bytes in a v2 session" in seen["R-NAK-ORDER"]
    assert "refused with NAK 1" in seen["R-LOOP"] and "refused with NAK 1" in seen["R-FORCE"]
    assert report.device.version == 2 and report.exit_status == 0


@pytest.mark.slow
def test_a_v3_device_built_before_clock_passes_r_clock_with_nak_1():
    """A v3 device built before CLOCK (0x09) existed: no ``features`` bit 5, and CLOCK not in its table, so it
    answers NAK 1 as rule 1 of R-NAK-ORDER asks. R-CLOCK passes (it failed, expecting NAK 4 alone)."""
    from ultraglide.devices import protocol as p
    from ultraglide.devices.sim.lies import Lies

    plate = not_in_its_table(PtyPlate(PROFILE), (p.CLOCK,)).start()
    try:
        probe = c.Probe(plate.path)
        try:
            features = probe.hello(3)[0].features
            plate.lies = Lies({"hello.features": features & ~p.FEATURE_CLOCK_STATED})  # the bit it never had
            answer = probe.command(p.CLOCK)  # what the device itself answers, before the check judges it
        finally:
            probe.close()
        report = c.check_device(plate.path, PROFILE, only=("R-CLOCK",))
    finally:
        plate.stop()
    assert features & p.FEATURE_CLOCK_STATED and answer[:2] == ("nak", p.NAK_UNKNOWN_TYPE)
    (verdict,) = report.verdicts
    assert verdict.outcome == c.PASS, verdict.line()
    assert "no clock stated: CLOCK refused with NAK 1" in verdict.seen and report.device.features == features - 32


def test_a_v3_device_still_owes_nak_4_for_what_it_knows():
    """The same NAK 1 from a device that speaks v3 is wrong: it knows SET_LOOP (R-NAK-ORDER, R-LOOP fail)."""
    plate = written_from_v2_alone(PtyPlate(PROFILE, max_version=3)).start()
    try:
        report = c.check_device(plate.path, PROFILE, only=("R-NAK-ORDER",))
    finally:
        plate.stop()
    (verdict,) = report.verdicts
    assert verdict.outcome == c.FAIL and "not NAK 4" in verdict.seen, verdict.line()


def test_a_port_in_use_is_refused_in_one_line(tmp_path):
    plate = PtyPlate(PROFILE).start()
    try:
        first = c.Probe(plate.path)
        try:
            line = assert_one_line_error(run_cli("plate", "check", "--device", f"serial:{plate.path}",
                                                 "--profile", "sim-plate", timeout=60))
        finally:
            first.close()
    finally:
        plate.stop()
    assert f"serial port {plate.path} is in use by another program" in line


def test_bad_options_are_one_line():
    line = assert_one_line_error(run_cli("plate", "check", "--rule", "R-NOTHING", timeout=60))
    assert "--rule R-NOTHING: no such rule" in line and "R-WATCHDOG" in line
    line = assert_one_line_error(run_cli("plate", "check", "--device", "null", timeout=60))
    assert "null speaks no protocol" in line
    line = assert_one_line_error(run_cli("plate", "check", "--device", "serial:/nonexistent/port",
                                         "--profile", "sim-plate", timeout=60))
    assert "cannot open serial port /nonexistent/port" in line


@pytest.mark.slow
def test_a_device_lost_mid_check_stops_it_rests_nothing_twice_and_exits_4(tmp_path):
    """plate-sim killed while the check runs: the check stops with what it saw so far, says so, exits 4."""
    server, link = serve(tmp_path)
    seen = []
    killed = False

    def say(verdict):
        nonlocal killed
        seen.append(verdict)
        if len(seen) == 2 and not killed:
            killed = True
            server.process.kill()

    try:
        started = time.monotonic()
        report = c.check_device(link, PROFILE, say=say)
        took = time.monotonic() - started
    finally:
        server.kill()
    assert report.aborted and report.lost and report.exit_status == 4, report.summary()
    assert len(report.verdicts) == 2 and took < 30
    assert "stopped:" in report.summary() and "could not finish" in report.verdict


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signalled_plate_check_rests_the_plate(tmp_path, signum):
    """Stopped while a rule streams to the plate: the check sends zero and ENABLE 0 on its way out, and exits
    128 + the signal's number."""
    server, link = serve(tmp_path)
    check = subprocess.Popen([sys.executable, "-m", "ultraglide", "plate", "check", "--device", f"serial:{link}",
                              "--profile", "sim-plate",
                              "--rule", "R-UNDERRUN", "--rule", "R-WATCHDOG"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        server.wait_line(lambda line: '"stream_started"' in line or '"enabled"' in line, timeout=120)
        check.send_signal(signum)
        out, err = check.communicate(timeout=60)
        server.wait_line(lambda line: '"disabled"' in line and '"host"' in line, timeout=30)
        status = plate_status(server)
    finally:
        if check.poll() is None:
            check.kill()
        server.finish(signal.SIGTERM)
    assert check.returncode == 128 + signum, err
    assert err.strip() == f"ultraglide: stopped ({signal.Signals(signum).name})"
    assert status == "disabled"


def plate_status(server) -> str:
    """The plate's output by its own events so far: enabled or disabled (the last such event)."""
    events = [json.loads(line) for line in server.seen if line.startswith("{")]
    changes = [event["event"] for event in events if event["event"] in ("enabled", "disabled")]
    return changes[-1] if changes else "disabled"


def test_a_checked_plate_is_left_disabled_at_zero():
    plate = PtyPlate(PROFILE).start()
    try:
        report = c.check_device(plate.path, PROFILE, only=("R-UNDERRUN",))  # leaves the output playing dry
        assert wait_for(lambda: not plate.simulator.enabled)
        assert plate.simulator.drive_um_pp == 0.0
    finally:
        plate.stop()
    assert report.exit_status == 0


def test_the_commands_guide_and_the_protocol_say_what_plate_check_does():
    guide = (ROOT / "docs" / "guide" / "commands.md").read_text(encoding="utf-8")
    assert "ultraglide plate check" in guide and "exit status 6" in guide
    assert "--break" in DOC and "`ultraglide plate check --device URL`" in DOC


def stalled_over_its_limit_codes(plate: PtyPlate, stall_s: float = 0.4) -> threading.Event:
    """The first time ``plate`` receives R-LIMIT's codes (1.25 × its limit), its whole simulator stops for
    ``stall_s``, as a descheduled process does: it then renders the stall at once and sends one frame for it,
    by when its buffer has run dry."""
    limit_code = int(PROFILE.max_amplitude_um_pp / PROFILE.full_scale_um_pp * 65535)
    codes = np.full(4, math.ceil(1.25 * limit_code), "<u2").tobytes()
    stalled = threading.Event()
    receive = plate.simulator.receive

    def hold() -> None:
        with plate.simulator._lock:  # what every thread of the simulator takes to render or to read
            time.sleep(stall_s)  # the stall itself: nothing to wait for

    def stalling(data: bytes) -> list[bytes]:
        if not stalled.is_set() and codes in data:
            stalled.set()
            threading.Thread(target=hold, daemon=True).start()
        return receive(data)

    plate.simulator.receive = stalling
    return stalled


@pytest.mark.slow
@pytest.mark.parametrize("breaks, outcome", [(("R-LIMIT",), c.FAIL), ((), c.PASS)])
def test_the_limit_is_judged_on_the_codes_played_when_the_simulator_stalls_over_them(breaks, outcome):
    """A device whose telemetry skipped the codes (its simulator stalled over them) and then held a value of its
    own once dry is asked again: a broken limiter is still seen, a sound one still passes."""
    plate = PtyPlate(PROFILE, breaks=breaks).start()
    try:
        stalled = stalled_over_its_limit_codes(plate)
        report = c.check_device(plate.path, PROFILE, only=("R-LIMIT",))
    finally:
        plate.stop()
    (verdict,) = report.verdicts
    assert stalled.is_set() and verdict.outcome == outcome, verdict.line()
