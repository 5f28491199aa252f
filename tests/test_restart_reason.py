"""Why the board last started, in its handshake (HELLO_REPLY v3's FEATURE_RESET_STATED: restart_reason:u8 and
restart_detail:u32 after the link's fields, docs/protocol.md): the wire layout packed by hand, the firmware core
stating what its port read at boot (through its host binding), and the host saying a restart in words. A board
restarting mid-run is tested on the emulated board (tests/test_firmware_faults.py)."""

import json
import re
import shutil
import struct

import pytest
from conftest import ROOT, run_cli, serve_plate
from qemu_board import next_event, said_in_hello
from ultraglide.devices import protocol as p
from ultraglide.devices.firmware import sil
from ultraglide.devices.firmware.boards import BOARD_INFO, build_images
from ultraglide.devices.firmware.qemu import QemuPlate
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.lies import Lies

V3_HEAD = struct.pack("<BfffIIffHHfBHB", 3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, 8.0, 1,
                      1000, 0)


RAM_PIN_WORDS = ("its reset pin or another reset with power kept (told from its RAM: the board has no reset-cause "
                 "register, so a debugger's reset or its watchdog's own reset looks the same)")
RAM_POWER_ON_WORDS = "power-on (told from its RAM: the board has no reset-cause register)"


def reply(features, **fields):
    return p.HelloReply(3, 25000.0, 8.0, 6.0, 1000, 48000, 20000.0, 28000.0, 100, 250, "board", 8.0, 1, 1000,
                        features, **fields)


def with_features(head: bytes, features: int) -> bytes:
    return head[:40] + bytes([features])


def test_the_two_fields_come_after_the_links_and_before_the_name():
    both = p.FEATURE_LINK_STATED | p.FEATURE_RESET_STATED
    payload = p.hello_reply_payload(reply(both, link_bytes_per_s=9000, q=150.0, restart_reason=1, restart_detail=2))
    assert payload == with_features(V3_HEAD, both) + struct.pack("<If", 9000, 150.0) + struct.pack("<BI", 1, 2) + \
        b"board"
    alone = p.hello_reply_payload(reply(p.FEATURE_RESET_STATED, restart_reason=2, restart_detail=0x8200))
    assert alone == with_features(V3_HEAD, p.FEATURE_RESET_STATED) + struct.pack("<BI", 2, 0x8200) + b"board"
    parsed = p.parse_hello_reply(alone)
    assert (parsed.restart_reason, parsed.restart_detail, parsed.name, parsed.link_bytes_per_s) == \
        (2, 0x8200, "board", 0)


def test_a_reply_without_the_bit_states_nothing_and_one_cut_short_is_refused():
    parsed = p.parse_hello_reply(with_features(V3_HEAD, 0) + b"board")
    assert (parsed.restart_reason, parsed.restart_words(), parsed.name) == (None, None, "board")
    with pytest.raises(p.ProtocolError, match="shorter than the 46 its features say"):
        p.parse_hello_reply(with_features(V3_HEAD, p.FEATURE_RESET_STATED) + b"\x01")


@pytest.mark.parametrize("reason, detail, words", [
    (p.RESTART_POWER_ON, 0, "power-on"),
    (p.RESTART_WATCHDOG, 2, "its watchdog expired (the block interrupt's mark missing)"),
    (p.RESTART_WATCHDOG, 1, "its watchdog expired (the main loop's mark missing)"),
    (p.RESTART_WATCHDOG, 0, "its watchdog expired (the block interrupt's and the main loop's marks missing)"),
    (p.RESTART_FAULT, 0x400, "a fault handler reset it (fault status 0x00000400)"),
    (p.RESTART_PIN, 0, "its reset pin"),
    (p.RESTART_PIN, 1, RAM_PIN_WORDS),  # bit 0: told from its RAM (no reset-cause register)
    (p.RESTART_POWER_ON, 1, RAM_POWER_ON_WORDS),
    (9, 0, "reason 9"),
])
def test_the_reason_in_words(reason, detail, words):
    assert reply(p.FEATURE_RESET_STATED, restart_reason=reason, restart_detail=detail).restart_words() == words


def hello_of(core: sil.FirmwareCore, version: int = 3) -> p.HelloReply:
    core.receive(p.encode_frame(p.HELLO, 1, p.hello_payload(version)))
    core.poll()  # replies are encoded in the main loop
    (frame,) = [f for f in p.FrameDecoder().feed(core.transmit()) if f.kind == p.HELLO_REPLY]
    return p.parse_hello_reply(frame.payload)


@pytest.mark.parametrize("link", [0, 14000])
def test_the_firmware_core_states_what_its_port_read_at_boot(link):
    core = sil.FirmwareCore(q=180.0, link_bytes_per_s=link, sim_faults=False, reset_stated=True,
                            reset_reason=p.RESTART_WATCHDOG, reset_detail=2)
    stated = hello_of(core)
    assert stated.features & p.FEATURE_RESET_STATED and (stated.restart_reason, stated.restart_detail) == (1, 2)
    assert (stated.link_bytes_per_s, stated.name) == (link, "ultraglide plate simulator")
    assert hello_of(core, version=2).restart_reason is None  # v2's layout has no room for it


def test_the_firmware_core_refuses_a_reason_it_cannot_state():
    with pytest.raises(Exception, match="refused its configuration"):
        sil.FirmwareCore(reset_stated=True, reset_reason=p.RESTART_PIN + 1)
    with pytest.raises(Exception, match="refused its configuration"):
        sil.FirmwareCore(features=1 | p.FEATURE_RESET_STATED)  # the bit is the core's to set


def test_play_says_how_the_board_came_to_be_running_and_does_not_count_it_a_fault():
    features = p.FEATURE_AMPLITUDE_LOOP | p.FEATURE_BRAKING | p.FEATURE_LINK_STATED | p.FEATURE_RESET_STATED
    plate = serve_plate(load_profile("sim-plate"), lies=Lies({"hello.features": features, "hello.restart_reason": 2,
                                                              "hello.restart_detail": 0x200}))
    try:
        result = run_cli("play", "grating-1mm", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                         "--duration-s", 2, timeout=300)
    finally:
        plate.stop()
    assert "the plate driver last started after a restart: a fault handler reset it (fault status 0x00000200)" \
        in result.stdout + result.stderr
    assert "restarted itself" not in result.stdout  # a restart before the run is no fault of the run
    assert result.returncode == 0, (result.stdout, result.stderr)


def test_plate_check_says_why_the_board_last_started():
    features = p.FEATURE_AMPLITUDE_LOOP | p.FEATURE_BRAKING | p.FEATURE_LINK_STATED | p.FEATURE_RESET_STATED
    plate = serve_plate(load_profile("sim-plate"), lies=Lies({"hello.features": features, "hello.restart_reason": 4,
                                                              "hello.restart_detail": 1}))
    try:
        text = run_cli("plate", "check", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                       "--rule", "R-VERSION", timeout=300)
        as_json = run_cli("plate", "check", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                          "--rule", "R-VERSION", "--json", timeout=300)
    finally:
        plate.stop()
    assert text.returncode == 0 and as_json.returncode == 0, (text.stderr, as_json.stderr)
    assert f"; why it last started: {RAM_PIN_WORDS}" in text.stdout.splitlines()[0]
    assert json.loads(as_json.stdout)["device"]["last_started"] == RAM_PIN_WORDS


UG_RESET_DETAIL_FROM_RAM = 1  # ports/common/ug_safety.h: told from the RAM kept, no reset-cause register read


def test_the_hosts_bit_for_told_from_ram_is_the_firmwares():
    header = (ROOT / "devices/firmware/ports/common/ug_safety.h").read_text()
    stated = re.search(r"#define UG_RESET_DETAIL_FROM_RAM (\d+)u", header)
    assert int(stated.group(1)) == p.RESTART_DETAIL_FROM_RAM == UG_RESET_DETAIL_FROM_RAM


@pytest.mark.slow
@pytest.mark.qemu
@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
                    reason="needs gcc-arm-none-eabi, libnewlib-arm-none-eabi and qemu-system-arm")
@pytest.mark.parametrize("board", ["netduinoplus2", "mps2-an386"])
def test_a_board_without_a_reset_cause_register_tells_its_reset_button_from_power_on_by_its_ram(one_qemu, board):
    """Neither QEMU's model of the AN386 (its SCC and FPGAIO hold no reset cause) nor its STM32F405 (no RCC: RCC_CSR
    reads 0) has a register that says why the board started, so both QEMU images tell it from their RAM: a mark
    set at every boot survives a reset that keeps power and not a power-on. A QEMU just started (RAM zero) says
    power-on; QEMU's ``system_reset`` (the reset button: processor and devices reset, RAM kept, no record of the
    firmware's) says its reset pin; a fault's own record still wins after it, and the button once more says pin.
    Each says in its detail (bit 0) that the RAM told it, and a host hears both in the handshake."""
    image = build_images(board, ["qemu"])[0]
    with QemuPlate(image.elf_path, machine=BOARD_INFO[board].machine) as plate:
        boot = next_event(plate, ("boot",))
        assert (boot["reset_reason"], boot["reset_from"]) == ("power-on", "ram")
        reply = said_in_hello(plate)
        assert (reply.restart_reason, reply.restart_detail, reply.restart_words()) == \
            (p.RESTART_POWER_ON, UG_RESET_DETAIL_FROM_RAM, RAM_POWER_ON_WORDS)
        for _ in range(2):
            next_event(plate, ("stats",))  # running: a second of the board's clock
            plate.press_reset()
            boot = next_event(plate, ("boot",))
            assert (boot["reset_reason"], boot["reset_from"]) == ("pin", "ram") and "injected" not in boot
            reply = said_in_hello(plate)
            assert (reply.restart_reason, reply.restart_detail, reply.restart_words()) == \
                (p.RESTART_PIN, UG_RESET_DETAIL_FROM_RAM, RAM_PIN_WORDS)
            next_event(plate, ("stats",))
            plate.inject_fault("hard-fault")  # the firmware's own record, not the RAM's mark, says a fault
            boot = next_event(plate, ("boot",))
            assert (boot["reset_reason"], boot["injected"]) == ("fault", "hard-fault") and "reset_from" not in boot
            assert said_in_hello(plate).restart_reason == p.RESTART_FAULT
        next_event(plate, ("stats",))
        plate.press_reset()  # and a command's words say it: plate check's first line
        assert next_event(plate, ("boot",))["reset_reason"] == "pin"
        check = run_cli("plate", "check", "--device", f"serial:{plate.path}", "--profile", "sim-plate",
                        "--rule", "R-VERSION", timeout=300)
        assert f"; why it last started: {RAM_PIN_WORDS}" in check.stdout.splitlines()[0], check.stdout + check.stderr
