"""The evdev touch panel reader (devices/touch/evdev.py): real input_event records, packed here from the kernel's
layout (linux/input.h: struct timeval as two 64-bit longs, __u16 type, __u16 code, __s32 value; the codes from
linux/input-event-codes.h written out by hand), written into a real FIFO and read back as touch frames: two slots,
a lift, a replaced contact, SYN_DROPPED, a single-touch panel, records split across reads, a panel that goes away,
and the nodes it refuses."""

import os
import select
import struct
import threading
import time

import pytest
from ultraglide.devices.rig import RigError, load_rig
from ultraglide.devices.touch.evdev import (
    AxisRange,
    Contact,
    PanelGone,
    PanelRanges,
    PanelReader,
    TouchPanelError,
    TouchPanelUsageError,
    eviocgabs,
    given_ranges,
)

# linux/input-event-codes.h
EV_SYN, EV_KEY, EV_ABS = 0, 1, 3
SYN_REPORT, SYN_DROPPED = 0, 3
BTN_TOUCH = 330
ABS_X, ABS_Y, ABS_PRESSURE = 0, 1, 24
ABS_MT_SLOT, ABS_MT_POSITION_X, ABS_MT_POSITION_Y, ABS_MT_TRACKING_ID, ABS_MT_PRESSURE = 47, 53, 54, 57, 58
RANGES = PanelRanges(AxisRange(0, 1000), AxisRange(0, 500), AxisRange(0, 255))


def record(t_s: float, kind: int, code: int, value: int) -> bytes:
    """One struct input_event as a 64-bit Linux kernel writes it (native byte order)."""
    seconds = int(t_s)
    return struct.pack("=qqHHi", seconds, round((t_s - seconds) * 1e6), kind, code, value)


def frame(t_s: float, *events) -> bytes:
    """Events (kind, code, value) at ``t_s`` and the SYN_REPORT that ends their frame."""
    return b"".join(record(t_s, *event) for event in events) + record(t_s, EV_SYN, SYN_REPORT, 0)


def mt(code: int, value: int) -> tuple:
    return EV_ABS, code, value


@pytest.fixture
def fifo(tmp_path):
    """(reader, write): a PanelReader on a real FIFO, and a function writing bytes into it."""
    path = tmp_path / "panel"
    os.mkfifo(path)
    reader = PanelReader(str(path), RANGES)
    writer = os.open(path, os.O_WRONLY)
    yield reader, lambda data: os.write(writer, data), lambda: os.close(writer)
    reader.close()
    try:
        os.close(writer)
    except OSError:
        pass


def frames(reader, count: int, timeout_s: float = 10.0) -> list:
    """Read until ``count`` frames have come (waiting on the node, as a loop's add_reader does)."""
    got, deadline = [], time.monotonic() + timeout_s
    while len(got) < count and time.monotonic() < deadline:
        ready, _, _ = select.select([reader.fd], [], [], 0.5)
        if ready:
            got += reader.read()
    return got


def test_two_slots_move_lift_and_keep_their_values(fifo):
    reader, write, _ = fifo
    write(frame(100.0, mt(ABS_MT_SLOT, 0), mt(ABS_MT_TRACKING_ID, 10), mt(ABS_MT_POSITION_X, 100),
                mt(ABS_MT_POSITION_Y, 200), mt(ABS_MT_PRESSURE, 30)))
    write(frame(100.01, mt(ABS_MT_SLOT, 1), mt(ABS_MT_TRACKING_ID, 11), mt(ABS_MT_POSITION_X, 900),
                mt(ABS_MT_POSITION_Y, 400), mt(ABS_MT_PRESSURE, 50)))
    # only what changed is sent: slot 0's x, slot 1's y
    write(frame(100.02, mt(ABS_MT_SLOT, 0), mt(ABS_MT_POSITION_X, 110), mt(ABS_MT_SLOT, 1),
                mt(ABS_MT_POSITION_Y, 410)))
    write(frame(100.03, mt(ABS_MT_SLOT, 0), mt(ABS_MT_TRACKING_ID, -1)))  # slot 0 lifts
    write(frame(100.04, mt(ABS_MT_POSITION_X, 500)))  # the current slot is 0, which holds no contact: nothing
    write(frame(100.05, mt(ABS_MT_SLOT, 1), mt(ABS_MT_POSITION_X, 905)))
    got = frames(reader, 5)
    assert [f.contacts for f in got] == [
        (Contact(0, "down", 100, 200, 30, 100.0),),
        (Contact(1, "down", 900, 400, 50, 100.01),),
        (Contact(0, "move", 110, 200, 30, 100.02), Contact(1, "move", 900, 410, 50, 100.02)),
        (Contact(0, "up", 110, 200, 30, 100.03),),
        (Contact(1, "move", 905, 410, 50, 100.05),),
    ]
    assert reader.parser.counts.frames == 6  # the empty frame counted, not returned


def test_a_contact_replaced_in_its_slot_is_a_lift_then_a_touch(fifo):
    reader, write, _ = fifo
    write(frame(5.0, mt(ABS_MT_TRACKING_ID, 1), mt(ABS_MT_POSITION_X, 10), mt(ABS_MT_POSITION_Y, 20)))
    write(frame(5.5, mt(ABS_MT_TRACKING_ID, 2), mt(ABS_MT_POSITION_X, 30)))  # its lift was never seen
    got = frames(reader, 2)
    assert got[1].contacts == (Contact(0, "up", 10, 20, None, 5.5), Contact(0, "down", 30, 20, None, 5.5))


def test_syn_dropped_discards_to_the_next_report_and_lifts_everything(fifo):
    reader, write, _ = fifo
    write(frame(1.0, mt(ABS_MT_TRACKING_ID, 7), mt(ABS_MT_POSITION_X, 100), mt(ABS_MT_POSITION_Y, 100)))
    write(frame(1.1, mt(ABS_MT_SLOT, 1), mt(ABS_MT_TRACKING_ID, 8), mt(ABS_MT_POSITION_X, 300),
                mt(ABS_MT_POSITION_Y, 300)))
    write(record(1.2, EV_SYN, SYN_DROPPED, 0) + frame(1.3, mt(ABS_MT_POSITION_X, 999), mt(ABS_MT_TRACKING_ID, 9)))
    write(frame(1.4, mt(ABS_MT_POSITION_X, 310)))  # slot 1's finger, still down: its contact is not known any more
    write(frame(1.5, mt(ABS_MT_TRACKING_ID, -1)))  # it lifts
    write(frame(1.6, mt(ABS_MT_TRACKING_ID, 12)))  # a new one, where slot 1's last x was 310: y not known yet
    write(frame(1.7, mt(ABS_MT_POSITION_Y, 320)))
    got = frames(reader, 4)
    dropped = got[2]
    assert dropped.resynced and dropped.t_s == pytest.approx(1.3)
    assert set(dropped.contacts) == {Contact(0, "up", 100, 100, None, 1.3), Contact(1, "up", 300, 300, None, 1.3)}
    assert got[3].contacts == (Contact(1, "down", 310, 320, None, 1.7),)
    assert len(got) == 4 and reader.parser.counts.drops == 1


def test_a_single_touch_panel(fifo):
    reader, write, _ = fifo
    write(frame(2.0, (EV_KEY, BTN_TOUCH, 1), (EV_ABS, ABS_X, 40), (EV_ABS, ABS_Y, 60), (EV_ABS, ABS_PRESSURE, 9)))
    write(frame(2.1, (EV_ABS, ABS_Y, 61)))
    write(frame(2.2, (EV_KEY, BTN_TOUCH, 0)))
    assert [f.contacts for f in frames(reader, 3)] == [(Contact(0, "down", 40, 60, 9, 2.0),),
                                                       (Contact(0, "move", 40, 61, 9, 2.1),),
                                                       (Contact(0, "up", 40, 61, 9, 2.2),)]


def test_a_multi_touch_panel_s_single_touch_emulation_is_ignored(fifo):
    reader, write, _ = fifo
    write(frame(3.0, mt(ABS_MT_TRACKING_ID, 4), mt(ABS_MT_POSITION_X, 70), mt(ABS_MT_POSITION_Y, 80),
                (EV_KEY, BTN_TOUCH, 1), (EV_ABS, ABS_X, 70), (EV_ABS, ABS_Y, 80)))
    write(frame(3.1, mt(ABS_MT_POSITION_X, 71), (EV_ABS, ABS_X, 71)))
    assert [f.contacts for f in frames(reader, 2)] == [(Contact(0, "down", 70, 80, None, 3.0),),
                                                       (Contact(0, "move", 71, 80, None, 3.1),)]


def test_records_split_across_reads_are_joined(fifo):
    reader, write, _ = fifo
    data = frame(4.0, mt(ABS_MT_TRACKING_ID, 3), mt(ABS_MT_POSITION_X, 1), mt(ABS_MT_POSITION_Y, 2))
    write(data[:37])
    assert frames(reader, 1, timeout_s=0.5) == []
    write(data[37:])
    assert frames(reader, 1)[0].contacts == (Contact(0, "down", 1, 2, None, 4.0),)


def test_memory_is_bounded_slots_beyond_sixteen_and_a_frame_that_never_ends(fifo):
    reader, write, _ = fifo
    write(frame(6.0, mt(ABS_MT_SLOT, 40), mt(ABS_MT_TRACKING_ID, 1), mt(ABS_MT_POSITION_X, 5),
                mt(ABS_MT_POSITION_Y, 5)))
    endless = record(6.1, *mt(ABS_MT_POSITION_X, 6)) * 5000  # 5000 events and no SYN_REPORT: taken as a drop
    write(frame(6.05, mt(ABS_MT_SLOT, 0), mt(ABS_MT_TRACKING_ID, 2), mt(ABS_MT_POSITION_X, 1),
                mt(ABS_MT_POSITION_Y, 1)))
    writer = threading.Thread(target=write, args=(endless + frame(6.2),))  # more than a FIFO holds: read meanwhile
    writer.start()
    got = frames(reader, 2)
    writer.join(10)
    assert got[0].contacts == (Contact(0, "down", 1, 1, None, 6.05),)  # slot 40's contact was not followed
    assert got[1].resynced and got[1].contacts == (Contact(0, "up", 1, 1, None, 6.2),)
    counts = reader.parser.counts
    assert counts.slots_ignored == 1 and counts.drops == 1 and len(reader.parser._partial) < 24


def test_a_panel_that_goes_away_is_said_in_one_line(fifo):
    reader, write, close = fifo
    write(frame(7.0, mt(ABS_MT_TRACKING_ID, 1), mt(ABS_MT_POSITION_X, 1), mt(ABS_MT_POSITION_Y, 1)))
    assert len(frames(reader, 1)) == 1
    close()
    select.select([reader.fd], [], [], 10)
    with pytest.raises(PanelGone) as gone:
        reader.read()
    assert str(gone.value) == f"the touch panel {reader.path} went away (its events ended)"


def test_nodes_it_cannot_read_are_refused_in_one_line(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(TouchPanelUsageError, match="is a FIFO, not an evdev device.*--touch-range x=MIN:MAX"):
        PanelReader(str(fifo), None)
    with pytest.raises(TouchPanelUsageError, match="a character device but not an evdev one"):
        PanelReader("/dev/null", None)  # the ioctl asking for its axes: ENOTTY
    (tmp_path / "plain").write_bytes(b"")
    with pytest.raises(TouchPanelUsageError, match="not a device nor a FIFO"):
        PanelReader(str(tmp_path / "plain"), RANGES)
    with pytest.raises(TouchPanelUsageError, match="no such file"):
        PanelReader(str(tmp_path / "absent"), RANGES)
    assert TouchPanelUsageError.exit_status == 2 and issubclass(TouchPanelUsageError, TouchPanelError)


def test_the_ioctl_numbers_are_the_kernel_s():
    # _IOR('E', 0x40 + abs, struct input_absinfo): read (2) << 30, 24 bytes << 16, 'E' << 8, nr; strace prints
    # EVIOCGABS(ABS_X) as 0x80184540
    assert eviocgabs(ABS_X) == 0x80184540
    assert eviocgabs(ABS_MT_POSITION_Y) == 0x80184540 + ABS_MT_POSITION_Y


def test_ranges_from_the_rig_and_options(tmp_path):
    assert given_ranges([], None) is None
    ranges = given_ranges(["pressure=0:1023"], {"x": (0, 4095), "y": (-100, 100)})
    assert (ranges.x, ranges.y, ranges.pressure) == (AxisRange(0, 4095), AxisRange(-100, 100), AxisRange(0, 1023))
    assert ranges.y.unit(50) == 0.75 and ranges.x.unit(-5) == 0.0 and ranges.x.unit(5000) == 1.0
    assert given_ranges(["x=10:20"], {"x": (0, 4095), "y": (0, 9)}).x == AxisRange(10, 20)  # an option wins
    for bad in ("x=5:1", "z=0:1", "x=0-100", "x=a:b", "x=0:99999999999"):
        with pytest.raises(TouchPanelUsageError, match="AXIS=MIN:MAX"):
            given_ranges([bad, "y=0:1"])
    with pytest.raises(TouchPanelUsageError, match="y range is not given"):
        given_ranges(["x=0:1"])
    rig = tmp_path / "rig.toml"
    plate = "[plate]\nresonance_hz = 25000\nq = 200\nmax_amplitude_um_pp = 5\nfull_scale_um_pp = 8\n"
    rig.write_text(plate + "[touch]\nx_range = [0, 4095]\ny_range = [0, 2047]\npressure_range = [0, 255]\n")
    touch = load_rig(rig).touch
    assert touch.axis_ranges == {"x": (0, 4095), "y": (0, 2047), "pressure": (0, 255)}
    assert load_rig(rig).as_dict()["touch"]["y_range"] == [0, 2047]
    for text, said in (("x_range = [0, 4095]\n", "without the other"), ("x_range = [5, 5]\ny_range = [0, 1]\n",
                                                                        "min < max"),
                       ("x_range = [0.5, 9]\ny_range = [0, 1]\n", "whole numbers"),
                       ("x_range = [0, 1, 2]\ny_range = [0, 1]\n", "[min, max]")):
        rig.write_text(plate + "[touch]\n" + text)
        with pytest.raises(RigError, match=said) as refused:
            load_rig(rig)
        assert "\n" not in str(refused.value)
