"""The real-time engine in its own process: real spawned processes, the simulated plate on a real pty,
real signals. Every wait is on a condition with a generous deadline."""

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error, run_cli, wait_for
from ultraglide.devices.profiles import load_profile
from ultraglide.devices.sim.pty_plate import PtyPlate
from ultraglide.render.engine import Engine, EngineConfig, EngineError
from ultraglide.textures.fileformat import save_texture
from ultraglide.textures.texture import Texture

# the default model, Monnoyer's law above a floor d = 0.1: d + (1 - d) exp(-(a_pp/2)^2 / (2 tau^2)), tau = 1.32 µm
# zero-to-peak, solved by hand for 0.5
HALF_FRICTION_UM_PP = 2 * 1.32 * math.sqrt(-2 * math.log((0.5 - 0.1) / (1 - 0.1)))  # 3.362 µm p-p
STICKY = (20.0, 25.0)  # ratio 1: the plate at rest
SLIPPERY = (60.0, 25.0)  # ratio 0.5


@pytest.fixture
def steps(tmp_path):
    """A texture whose left half is at rest (1.0) and right half halves friction (0.5)."""
    texture = Texture(np.array([[1.0, 0.5]], dtype=np.float32), 80.0, 50.0, outside="clamp", name="steps")
    return str(save_texture(texture, tmp_path / "steps.png"))



def hold(engine, where, until, timeout=30.0):
    """Keep a finger at ``where`` (120 Hz reports) until ``until(status)`` or the deadline."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        engine.touch(time.perf_counter(), *where)
        status = engine.status()
        if until(status):
            return status
        time.sleep(1 / 120)
    raise AssertionError(f"not reached in {timeout} s: {engine.status().words()}")


def test_touches_reach_the_plate_and_stop_rests_it(steps):
    """The simulated plate served here, on a real pty: what it does is observed beside the engine."""
    plate = PtyPlate(load_profile("sim-plate")).start()
    sim = plate.simulator
    try:
        with Engine.start(EngineConfig(texture=steps, device=f"serial:{plate.path}")) as engine:
            engine.wait_ready(60)
            assert engine.ready
            # on the slippery half the plate settles at the amplitude the model gives for ratio 0.5
            status = hold(engine, SLIPPERY, lambda s: abs(sim.amplitude_um_pp - HALF_FRICTION_UM_PP) < 0.02)
            assert status.history.target_ratio[-1] == pytest.approx(0.5, abs=1e-3)
            assert status.history.commanded_um_pp[-1] == pytest.approx(HALF_FRICTION_UM_PP, abs=0.01)
            assert status.state == "running" and status.touches > 0
            # on the sticky half it comes back to rest, and up again
            hold(engine, STICKY, lambda s: sim.amplitude_um_pp < 0.02)
            hold(engine, SLIPPERY, lambda s: sim.amplitude_um_pp > 3.0)
            assert sim.enabled
        final = engine.final_status
        assert final.state == "stopped" and not engine.alive
        assert not sim.enabled  # zero and disable, acknowledged before stop() returned
        assert wait_for(lambda: sim.amplitude_um_pp < 0.01)
        assert final.device_status["fault_counts"]["over-limit"] == 0
    finally:
        plate.stop()


def test_status_counts_blocks_at_the_devices_pace_and_pause_rests(steps):
    with Engine.start(EngineConfig(texture=steps, device="null", rate_hz=96000)) as engine:
        engine.wait_ready(60)
        first = hold(engine, SLIPPERY, lambda s: s.blocks > 10 and s.history.commanded_um_pp[-1] > 3.0)
        started = time.perf_counter()
        second = hold(engine, SLIPPERY, lambda s: time.perf_counter() - started > 1.0)
        elapsed = second.history.time_s[-1] - first.history.time_s[-1]
        # the null sink pulls 96 000 frames a second: 12 000 control samples a second, whatever the load
        rendered = second.control_samples - first.control_samples
        assert rendered == pytest.approx(12000 * elapsed, rel=0.05, abs=240)
        assert second.blocks > first.blocks
        assert second.block_p50_us is not None and 0 < second.block_p50_us <= second.block_p99_us
        assert "SCHED_FIFO" in second.priority or "nice" in second.priority or "normal" in second.priority
        engine.pause(True)
        paused = hold(engine, SLIPPERY, lambda s: s.history.commanded_um_pp[-1] < 1e-3)
        assert paused.state == "paused"
        engine.pause(False)
        hold(engine, SLIPPERY, lambda s: s.history.commanded_um_pp[-1] > 3.0)
        engine.set_texture("grating-1mm")  # a live change; a bad one is one line
        with pytest.raises(EngineError, match="no texture"):
            engine.set_texture("no-such-texture")
        engine.set_force(0.3)
        with pytest.raises(EngineError, match="positive"):
            engine.set_force(-1.0)


@pytest.mark.parametrize("config, fragment", [
    (EngineConfig(texture="no-such-texture", device="null"), "no texture"),
    (EngineConfig(texture="grating-1mm", device="bluetooth"), "unknown device"),
    (EngineConfig(texture="grating-1mm", model="no-such-model", device="null"), "model"),
])
def test_a_bad_config_is_one_line(config, fragment):
    with pytest.raises(EngineError, match=fragment) as caught:
        Engine.start(config)
    assert "\n" not in str(caught.value)


def test_a_device_that_fails_is_one_line_and_leaves_nothing(tmp_path):
    with pytest.raises(EngineError, match="outside") as caught:  # refused when the device is opened
        Engine.start(EngineConfig(texture="grating-1mm", device=f"wav:{tmp_path / 'x.wav'}", carrier_hz=35000))
    assert "\n" not in str(caught.value) and list(tmp_path.iterdir()) == []  # no partial recording
    master, slave = os.openpty()  # a port where nobody answers: the handshake fails, when the device is opened
    engine = None  # (the first handshake that asks the link's capacity) or when it starts
    try:
        with pytest.raises(EngineError, match="no answer") as caught:
            engine = Engine.start(EngineConfig(texture="grating-1mm", device=f"serial:{os.ttyname(slave)}"))
            engine.wait_ready(60)
        assert "\n" not in str(caught.value)
        if engine is not None:
            engine.stop()
            assert not engine.alive
    finally:
        os.close(master)
        os.close(slave)


def test_play_reports_the_engine_figures(tmp_path):
    import json

    status = json.loads(run_cli("play", "grating-1mm", "--device", "null", "--duration-s", "0.5", "--json",
                                check=True).stdout)
    assert status["blocks"] > 50 and status["block_p99_us"] >= status["block_p50_us"] > 0
    # 0.5 s of 120 Hz reports, each sent or skipped as late (a busy machine); every one sent reached the engine,
    # with the finger's lift at the end
    assert status["touch_reports_sent"] + status["touch_reports_skipped"] == 60
    assert status["touches"] == status["touch_reports_sent"] + 1 and status["state"] == "stopped"
    assert {"late_blocks", "underruns", "priority"} <= status.keys()
    assert "unknown device" in assert_one_line_error(run_cli("play", "grating-1mm", "--device", "bluetooth"))


PARENT = """
import select, sys, time
from ultraglide.render.engine import Engine, EngineConfig
engine = Engine.start(EngineConfig(texture=sys.argv[1], device="serial:" + sys.argv[2]))
engine.wait_ready(60)
print(engine.info["pid"], flush=True)
while True:  # a finger held, reported at 120 Hz, until a line on stdin: then leave without engine.stop()
    engine.touch(time.perf_counter(), 60.0, 25.0)
    if select.select([sys.stdin], [], [], 1 / 120)[0]:
        break
"""


def test_a_replay_that_starts_late_sends_the_newest_report_due_and_counts_the_rest_as_skipped():
    """``play`` feeds a swipe's reports at their times; a quarter second late (a stalled process), the 31 reports
    due by then are one touch, the newest, and 30 skipped; the rest go at their times (or are skipped too, on a
    machine that stalls again): every report is sent or skipped."""
    from ultraglide.apps.commands.play import replay

    times = np.arange(60) / 120.0
    xs = 10.0 + np.arange(60.0)
    sent = []
    replayed = replay(lambda t, x, y, force: sent.append((x, force)), [(times, xs, xs, np.full(60, np.nan))],
                      time.perf_counter() - 0.25)
    assert replayed.sent == len(sent) and replayed.sent + replayed.skipped == 60 and replayed.skipped >= 30
    assert sent[0][0] >= xs[30] and sent[0][1] is None  # the newest due when it ran; no force known
    assert [x for x, _ in sent] == sorted(x for x, _ in sent) and sent[-1][0] == xs[-1]
    assert replayed.last == (xs[-1], xs[-1])


@pytest.mark.parametrize("ending", ["killed", "forgets to stop"])
def test_when_the_parent_goes_the_engine_rests_the_plate_and_exits(steps, ending):
    plate = PtyPlate(load_profile("sim-plate")).start()
    parent = subprocess.Popen([sys.executable, "-c", PARENT, steps, plate.path], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        engine_pid = int(parent.stdout.readline())
        sim = plate.simulator
        assert wait_for(lambda: abs(sim.amplitude_um_pp - HALF_FRICTION_UM_PP) < 0.1), sim.amplitude_um_pp
        if ending == "killed":
            parent.send_signal(signal.SIGKILL)  # no clean-up at all on the parent's side
        else:
            parent.stdin.write("leave\n")  # once the plate plays: it leaves, forgetting engine.stop()
            parent.stdin.flush()
        assert parent.wait(timeout=60) == (-signal.SIGKILL if ending == "killed" else 0)
        # disabled: only the driver's "enable off" does that (the plate's watchdog ramps but stays enabled)
        assert wait_for(lambda: not sim.enabled and sim.amplitude_um_pp < 0.01)

        def gone():
            try:
                os.kill(engine_pid, 0)
            except ProcessLookupError:
                return True
            return False

        assert wait_for(gone)
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        plate.stop()


@pytest.mark.parametrize("device", ["sim", "null"])
def test_latency_from_touch_to_output(device):
    import json

    figures = json.loads(run_cli("latency", "--device", device, "--steps", "12", "--json", check=True).stdout)
    engine, device_part, total = figures["engine_ms"], figures["device_ms"], figures["total_ms"]
    # a touch waits for the device's next pull, then one block is rendered: never less than 0, and
    # (median) not more than a device period plus a generous allowance for a loaded machine
    assert 0 < engine["p50"] <= engine["p99"]
    assert engine["p50"] < figures["block_ms"] + 20
    if device == "null":
        assert device_part == {"p50": 0.0, "p99": 0.0}  # the null sink holds nothing back
        assert figures["depth_corrections"] == 0  # no plate driver's lead to move
    else:  # the simulated plate responds after the engine: writer batch, link, jitter buffer
        assert device_part["p50"] > 0 and total["p50"] > engine["p50"]
        assert total["p50"] < 100  # tens of ms would be a broken link, not buffering
    human = run_cli("latency", "--device", device, "--steps", "3", check=True).stdout
    assert "engine" in human and "ms median" in human
    assert figures["model"] == "dynamic" and "model dynamic" in human  # the default, which plans


def test_latency_renders_with_the_model_asked_and_refuses_a_bad_one_in_one_line():
    import json

    figures = json.loads(run_cli("latency", "--device", "null", "--steps", "3", "--model", "stretched", "--json",
                                 check=True).stdout)
    assert figures["model"] == "stretched" and figures["engine_ms"]["p50"] > 0
    result = run_cli("latency", "--device", "null", "--steps", "3", "--model", "no-such-model")
    assert result.returncode != 0 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and "no-such-model" in result.stderr


def test_latency_on_the_audio_device_reports_portaudios_output_latency(tmp_path):
    import json

    from test_devices import ASOUNDRC

    (tmp_path / ".asoundrc").write_text(ASOUNDRC.format(path=tmp_path / "capture.raw"))
    figures = json.loads(run_cli("latency", "--device", "audio?latency=0.02&blocksize=256", "--profile", "sim-plate",
                                 "--steps", "5", "--json",
                                 env={"HOME": str(tmp_path)}, check=True).stdout)
    # PortAudio's output latency for a 20 ms request is about 20 ms (ALSA rounds to its periods)
    assert 10 < figures["device_ms"]["p50"] < 60
    assert figures["total_ms"]["p50"] > figures["device_ms"]["p50"]  # each step: engine part + device part


def test_preallocated_control_blocks_match_the_allocating_path():
    from ultraglide.render.physics.friction_models import ExponentialModel
    from ultraglide.render.renderer import Renderer
    from ultraglide.textures.library import resolve_texture

    def renderer():
        r = Renderer(resolve_texture("grating-1mm"), ExponentialModel(), load_profile("sim-plate"))
        for k in range(8):  # a finger moving at 100 mm/s, reported at 120 Hz
            r.push(100.0 + k / 120, 10.0 + k * 100 / 120, 25.0)
        return r

    plain, reused = renderer(), renderer()
    buffers = reused.control_buffers(64)
    first = None
    for k in range(50):
        now = 100.07 + k * 24 / 12000
        a = plain.control(24, now)
        b = reused.control(24, now, out=buffers)
        for name in ("time_s", "x_mm", "y_mm", "ratio", "target_um_pp", "amplitude_um_pp", "drive_um_pp",
                     "plate_um_pp"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        first = first or b
        assert b is first and np.shares_memory(b.drive_um_pp, buffers.drive_um_pp)  # the same arrays, refilled
    assert reused.control(100, 101.0, out=buffers).drive_um_pp.shape == (100,)  # beyond capacity: still served


def _tearing_writer(name, stop):
    import time

    from ultraglide.render.engine import shm
    from ultraglide.render.engine.shm import SharedBlock

    shared = SharedBlock.attach(name)
    k = 0
    while not (k % 64 == 0 and stop.is_set()):
        k += 1
        shared.fast[shm.SEQ] += 1
        shared.block_times[:] = k  # thousands of stores: a reader without the seqlock sees them half done
        shared.history[:] = k
        shared.fast[shm.BLOCKS] = k
        shared.fast[shm.SEQ] += 1
        time.sleep(0.0002)  # as the engine does, a round per block: a reader gets its turn between them
    shared.close()


@pytest.mark.slow
def test_status_snapshots_are_never_torn_by_a_writer_in_another_process():
    import multiprocessing

    from ultraglide.render.engine import shm
    from ultraglide.render.engine.shm import SharedBlock

    context = multiprocessing.get_context("spawn")
    shared = SharedBlock.create()
    stop = context.Event()
    writer = context.Process(target=_tearing_writer, args=(shared.name, stop))
    writer.start()
    seen = set()
    deadline = time.monotonic() + 120
    try:  # read until 200 different rounds were seen while the writer wrote (the writer runs until then)
        while len(seen) < 200 and time.monotonic() < deadline and writer.is_alive():
            header, times, history, _ = shared.read_fast()
            k = header[shm.BLOCKS]
            assert np.all(times == k) and np.all(history == k)  # one writer's round, whole
            seen.add(k)
    finally:
        stop.set()
        writer.join(30)
        shared.close()
    assert len(seen) >= 200  # it did read while the writer was writing


@pytest.mark.parametrize("device", ["sim", "null"])
def test_wait_ready_returns_once_the_device_has_taken_a_block(device):
    """As the module's example promises: right after ``wait_ready()`` the status says the engine runs."""
    with Engine.start(EngineConfig(texture="grating-1mm", device=device)) as engine:
        engine.wait_ready(60)
        status = engine.status()
        assert status.state == "running" and status.blocks >= 1, status.words()
        assert status.words().startswith(f"{device} running | ")


def test_an_engine_launched_and_abandoned_leaves_no_process_or_segment(steps):
    """Engine.launch returns while the engine loads; abandon() ends it before it serves."""
    import multiprocessing

    def ours() -> set[str]:  # the segments this process made (another test worker's engines make theirs)
        return {name for name in os.listdir("/dev/shm") if name.startswith(f"ultraglide_{os.getpid()}_")}

    segments = ours()
    launched = Engine.launch(EngineConfig(texture=steps, device="null"))
    assert multiprocessing.active_children()  # it runs, loading
    assert ours() > segments  # its segment, made here
    launched.abandon()
    assert not multiprocessing.active_children()
    assert ours() <= segments


FORKED_FROM_A_HEAP = r'''
import gc, json, sys
from ultraglide.render.engine import Engine, EngineConfig

def memory_kb(pid="self"):
    with open(f"/proc/{pid}/smaps_rollup") as rollup:
        return {line.split(":")[0]: int(line.split()[1]) for line in rollup if line.split()[-1] == "kB"}

before_kb = memory_kb()["Rss"]
heap = [[i] for i in range(1_000_000)]  # objects the collector tracks: a million lists
if sys.argv[1] == "frozen by the app":
    gc.freeze()
heap_kb = memory_kb()["Rss"] - before_kb
frozen = gc.get_freeze_count()
with Engine.start(EngineConfig(device="null", realtime_priority=False)) as engine:
    engine.wait_ready(60)
    engine_kb = memory_kb(engine.process.pid)["Private_Dirty"]
print(json.dumps({"heap_kb": heap_kb, "engine_private_kb": engine_kb, "frozen_before": frozen,
                  "frozen_after": gc.get_freeze_count()}))
'''


def test_an_engine_forked_from_an_app_with_many_objects_copies_none_of_them():
    """The engine collects its garbage once before it serves; forked from an app holding a million objects, that
    collection must not walk (and so copy into the engine, page by page) the app's objects: its private memory
    is that of an engine forked from an app that froze its objects itself, within a fifth of the heap's size
    (walking them copied 68 MB of a 115 MB heap). The app's own collector is left as it was."""
    runs = {}
    for how in ("as it is", "frozen by the app"):
        result = subprocess.run([sys.executable, "-c", FORKED_FROM_A_HEAP, how], capture_output=True, text=True,
                                timeout=300)
        assert result.returncode == 0, result.stderr
        runs[how] = json.loads(result.stdout)
    plain, frozen = runs["as it is"], runs["frozen by the app"]
    assert plain["heap_kb"] > 50_000 and frozen["frozen_before"] >= 1_000_000
    assert plain["engine_private_kb"] < frozen["engine_private_kb"] + 0.2 * plain["heap_kb"], runs
    assert plain["frozen_before"] == plain["frozen_after"] == 0  # nothing left frozen in the app
    assert frozen["frozen_after"] == frozen["frozen_before"]  # and the app's own freeze kept, not thawed
