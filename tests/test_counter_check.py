"""A device's counters are believed only as far as they can be true: a plate (scripted, on a real pty) whose
fault counter goes backwards is reported once as a device fault (exit status 3), its count not taken for a wrap
past 2**32; a real wrap and a real restart are counted as they are."""

import re

import pytest
from conftest import wait_for
from scripted_plate import PROFILE, ScriptedPlate
from sources import Constant
from test_exits import DEADLINE_S
from ultraglide.devices import protocol as p
from ultraglide.devices.counter_check import STEP_MAX, CounterCheck, plausible_restart
from ultraglide.devices.serial.plate import SerialPlate

OVERRUN_BIT = (p.FAULT_OVERRUN if hasattr(p, "FAULT_OVERRUN") else p.FAULT_UNDERRUN).bit_length() - 1
NAME = p.FAULT_NAMES[1 << OVERRUN_BIT]


def counts_with(bit: int, value: int) -> tuple[int, ...]:
    return tuple(value if k == bit else 0 for k in range(p.FAULT_BITS))


def run_against(**lies):
    with ScriptedPlate(**lies) as plate:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.start(Constant(1.0))
        assert wait_for(lambda: driver.telemetry_frames >= 60, timeout=DEADLINE_S)
        driver.stop()
    return driver


def test_a_counter_that_goes_backwards_is_a_device_fault_said_once():
    # the overrun counter counts 5, then from the 20th frame on says 3, 4, 3, 4 ...: backwards, again and again
    driver = run_against(counts=lambda k: counts_with(OVERRUN_BIT, 5 if k < 20 else 3 + (k % 2)))
    counts = driver.fault_counts()
    assert counts[NAME] < 100, counts  # not 4 294 967 294 × ... (the decrease taken for a wrap)
    report = driver.report()
    assert report.exit_status == 3, report.lines
    said = [line for line in report.lines if line.startswith("the plate reported counters that cannot be true")]
    assert len(said) == 1, report.lines
    # (from 5, or from 4 if the host's first telemetry came after the lie began)
    assert re.search(rf"fault count {NAME} went from [45] to 3, not a wrap or a restart", said[0]), said[0]


def test_a_wrap_past_2_32_is_counted_as_the_few_it_is():
    near = 2 ** 32 - 3  # 0xFFFFFFFD, then 1: four counted (0xFFFFFFFE, 0xFFFFFFFF, 0, 1)
    with ScriptedPlate(counts=lambda k: counts_with(OVERRUN_BIT, near)) as plate:
        driver = SerialPlate(plate.path, PROFILE, ack_timeout_s=10)
        driver.start(Constant(1.0))
        assert wait_for(lambda: driver.telemetry_frames >= 10, timeout=DEADLINE_S)  # its baseline is 0xFFFFFFFD
        plate.counts = lambda k: counts_with(OVERRUN_BIT, 1)
        seen = driver.telemetry_frames
        assert wait_for(lambda: driver.telemetry_frames >= seen + 10, timeout=DEADLINE_S)
        driver.stop()
    assert driver.fault_counts()[NAME] == 4
    assert not any("cannot be true" in line for line in driver.report().lines)


def test_the_check_itself_against_hand_counted_steps():
    check = CounterCheck()
    assert check.steps(("a", "b"), (10, 2), (7, 2 ** 32 - 2), restarted=False) == [3, 4]  # a step, a wrap
    assert check.steps(("a",), (STEP_MAX + 7,), (7,), restarted=False) == [STEP_MAX]
    assert check.steps(("a",), (STEP_MAX + 8,), (7,), restarted=False) == [0]  # one more: not believed
    assert check.steps(("a",), (3,), (1000,), restarted=True) == [3]  # a restart counts from zero
    assert check.count == 1 and check.words().count("went from") == 1
    assert plausible_restart(10, 50) and not plausible_restart(10_000, 50)


def test_the_bounds_are_the_documented_ones_counted_by_hand():
    """A million and a bit (2**20 = 1 048 576) a telemetry frame, u32 values, a restart's 64 frames of slack: the
    figures written out here, not read from the module."""
    check = CounterCheck()
    assert check.steps(("a",), (1_048_576,), (0,), restarted=False) == [1_048_576]
    assert check.steps(("a",), (1_048_577,), (0,), restarted=False) == [0]
    assert check.steps(("a",), (0,), (0,), restarted=False) == [0] and check.count == 1  # no step is a true one
    assert check.steps(("b",), (0,), (7,), restarted=True) == [0] and check.count == 1  # a restart to 0
    assert check.steps(("c",), (2 ** 32,), (2 ** 32 - 1,), restarted=False) == [0]  # not a u32: never believed
    assert check.steps(("d",), (-1,), (0,), restarted=True) == [0]
    assert check.count == 3
    assert plausible_restart(0, 0) and plausible_restart(50 + 64, 50) and not plausible_restart(50 + 65, 50)
    assert not plausible_restart(-1, 50)
    small = CounterCheck(step_max=10)  # a bound of one's own
    assert small.steps(("a", "b"), (10, 11), (0, 0), restarted=False) == [10, 0]
    with pytest.raises(ValueError):  # counters and names that differ in number: refused, not cut to the shorter
        small.steps(("a", "b"), (1,), (0, 0), restarted=False)


def test_the_words_name_each_counters_first_lie_and_count_every_one():
    check = CounterCheck()
    assert check.words() is None and check.first_s() == 0.0  # every counter believable: nothing to say
    check.steps(("late",), (5,), (9,), restarted=False)  # no time given
    assert check.first_s() == 0.0
    assert check.words() == ("the plate reported counters that cannot be true (late went from 9 to 5, not a wrap or "
                             "a restart; 1 such value in all): they were not counted")
    check.steps(("late", "lost"), (4, 1), (5, 3), restarted=False, at_s=2.5)  # late again (said once), lost now
    check.steps(("overrun", "nak", "trip"), (0, 0, 0), (1, 2, 3), restarted=False, at_s=1.5)
    assert check.count == 6 and check.first_s() == 1.5  # 1 + 2 + 3 values, 5 counters
    assert check.words() == ("the plate reported counters that cannot be true (late went from 9 to 5; lost went from "
                             "3 to 1; overrun went from 1 to 0; nak went from 2 to 0; 1 more, not a wrap or a "
                             "restart; 6 such values in all): they were not counted")
    four = CounterCheck()
    four.steps(("a", "b", "c", "d"), (0, 0, 0, 0), (1, 1, 1, 1), restarted=False)
    assert "; 1 more" not in four.words() and "d went from 1 to 0, not a wrap" in four.words()
