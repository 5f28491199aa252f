"""The engine against a real, paced sink: JACK's dummy backend, xruns counted by the clients.

Run: .venv/bin/python bench/bench_jack.py [--seconds 20] [--periods 64 256] [--repeat N] [--ui-cmd "COMMAND"] [--demo]

Starts ``jackd -d dummy -r 96000 -p PERIOD`` (realtime if allowed), then for each period, with and
without a CPU hog (``python3 -c 'while 1: pass'``) beside it, runs for ``--seconds``:

* a do-nothing client: a sounddevice callback on JACK that writes zeros (the yardstick: on a shared
  2-core machine even this misses deadlines now and then);
* the engine (its own process) on the same JACK output through PortAudio, with a scripted finger
  (touch reports at 120 Hz from this process, circling over a grating) and, with ``--ui-cmd``, a
  given command running beside it as the UI's load (e.g. the demo's scripted drag under Xvfb).

With ``--demo`` the engine measured is the demo's own: ``ultraglide demo --device audio:JACK`` under
Xvfb, the finger a 20 s xdotool drag at 120 Hz sweeping the first texture (the harness of
tests/xvfb_demo.py); its figures come from ``--stats`` (xruns counted from the first touch on). A
third client, ``nothing+UI``, is the do-nothing client again while the demo is dragged the same way on
the null device: the machine as busy as in the demo's run, without the demo's engine on JACK.

Prints block time p50/p99 (the callback's own time for the do-nothing client) and xruns per minute,
counted by the client (PortAudio's output-underflow flag, which JACK's xrun callback raises) and by
the server (its "XRun" log lines). Xruns come a few a minute, so one 20 s run says little: with
``--repeat N`` the two clients take turns N times in each case, and a last table adds their runs up
(xruns over minutes) and says whether the engine stayed within the do-nothing client's count.
Needs jackd (Debian: apt-get install jackd2).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RATE = 96000
BESIDE_UI = "nothing+UI"  # the do-nothing client beside the demo's UI dragged on the null device
HOG = [sys.executable, "-c", "while 1: pass"]

DO_NOTHING = """
import json, sys, time
import numpy as np, sounddevice as sd
seconds, warm_up = float(sys.argv[1]), float(sys.argv[2])
device = next(i for i, d in enumerate(sd.query_devices()) if d["max_output_channels"] > 0
              and sd.query_hostapis(d["hostapi"])["name"] == "JACK Audio Connection Kit")
times = np.zeros(1 << 20)
state = [0, 0]
def callback(out, frames, when, status):
    started = time.perf_counter()
    if status.output_underflow:
        state[1] += 1
    out.fill(0)
    times[state[0] % len(times)] = time.perf_counter() - started
    state[0] += 1
with sd.OutputStream(device=device, samplerate=96000, channels=1, dtype="float32", callback=callback):
    time.sleep(warm_up)
    first = list(state)
    print("warm", flush=True)
    time.sleep(seconds)
    last = list(state)
size = len(times)
window = np.array([times[k % size] for k in range(first[0], last[0])])
print(json.dumps({"callbacks": last[0] - first[0], "xruns": last[1] - first[1],
                  "p50_us": float(np.percentile(window, 50)) * 1e6, "p99_us": float(np.percentile(window, 99)) * 1e6}))
"""


FIND_JACK = """
import sounddevice as sd
print(next(i for i, d in enumerate(sd.query_devices()) if d["max_output_channels"] > 0
           and sd.query_hostapis(d["hostapi"])["name"] == "JACK Audio Connection Kit"))
"""
WARM_UP_S = 1.0  # client start-up (connecting, the graph reordering) is not what is measured


def jack_device() -> str:
    """PortAudio's index of the JACK output (asked in a subprocess: PortAudio here would outlive jackd)."""
    result = subprocess.run([sys.executable, "-c", FIND_JACK], capture_output=True, text=True, timeout=60)
    if result.returncode:
        raise RuntimeError("PortAudio lists no JACK output; is libportaudio2 built with JACK?")
    return result.stdout.strip()


class Jack:
    """A jackd dummy server for one period size; its log counts the server's xruns."""

    def __init__(self, period: int):
        self.log = Path(tempfile.mkstemp(prefix="jackd-", suffix=".log")[1])
        env = {**os.environ, "JACK_NO_AUDIO_RESERVATION": "1"}
        self.realtime = True
        for flags in (["-R"], ["--no-realtime"]):
            with self.log.open("w") as out:
                self.process = subprocess.Popen(["jackd", *flags, "-d", "dummy", "-r", str(RATE), "-p", str(period)],
                                                stdout=out, stderr=subprocess.STDOUT, env=env)
            if self._up():
                self.realtime = flags == ["-R"]
                return
            self.stop()
        raise RuntimeError(f"jackd did not start; see {self.log}")

    def _up(self) -> bool:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and self.process.poll() is None:
            if subprocess.run(["jack_lsp"], capture_output=True, env={**os.environ, "JACK_NO_START_SERVER": "1"}
                              ).returncode == 0:
                return True
            time.sleep(0.1)
        return False

    def xruns(self) -> int:
        return self.log.read_text(errors="replace").count("XRun")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def start_do_nothing(seconds: float) -> subprocess.Popen:
    """The do-nothing client, warmed up: it measures for ``seconds`` from when this returns."""
    client = subprocess.Popen([sys.executable, "-c", DO_NOTHING, str(seconds), str(WARM_UP_S)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if client.stdout.readline().strip() != "warm":
        raise RuntimeError(f"the do-nothing client failed: {client.stderr.read().strip()[-300:]}")
    return client


def run_do_nothing(seconds: float, jack: Jack) -> dict:
    client = start_do_nothing(seconds)
    before = jack.xruns()
    out, err = client.communicate(timeout=seconds + 60)
    figures = json.loads(out)
    figures["server_xruns"] = jack.xruns() - before
    return figures


def run_engine(seconds: float, device: str, ui_cmd: str | None, jack: Jack) -> dict:
    from ultraglide.render.engine import Engine, EngineConfig

    ui = subprocess.Popen(ui_cmd, shell=True) if ui_cmd else None
    try:
        with Engine.start(EngineConfig(texture="grating-1mm", device=f"audio:{device}")) as engine:
            engine.wait_ready()
            started = time.perf_counter()
            first = before = None
            while (now := time.perf_counter()) - started < seconds + WARM_UP_S:
                if first is None and now - started >= WARM_UP_S + 0.2:  # the device status lags 0.1 s
                    first, before = engine.status(), jack.xruns()
                phase = (now - started) * 2.0
                engine.touch(now, 40 + 30 * math.cos(phase), 25 + 15 * math.sin(phase))
                time.sleep(1 / 120)
            status = engine.status()
            server = jack.xruns() - before
    finally:
        if ui is not None:
            ui.terminate()
            ui.wait()
    return {"callbacks": status.blocks - first.blocks, "xruns": status.underruns - first.underruns,
            "server_xruns": server, "p50_us": status.block_p50_us, "p99_us": status.block_p99_us,
            "priority": status.priority}


def _xvfb_demo():
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from xvfb_demo import XvfbDemo

    return XvfbDemo


def _drag_ready(demo, seconds: float) -> list[tuple[int, int]]:
    """Wait for the demo's texture scene; the drag's points, 120 a second, sweeping it at 1 Hz."""
    demo.wait_for("^renderer ready", 120)
    demo.xdo("key", "t")
    demo.wait_for("^frame drawn: texture", 30)
    return [(round(640 + 300 * math.sin(2 * math.pi * i / 240)), 320) for i in range(int(seconds * 120))]


def run_do_nothing_beside_demo(seconds: float, jack: Jack) -> dict:
    """The do-nothing client while the demo, on the null device (no JACK client of its own), is dragged as
    in :func:`run_demo`: the machine as busy as in the demo's run, without the demo's engine on JACK."""
    with _xvfb_demo()("--device", "null") as demo:
        points = _drag_ready(demo, seconds)
        client = start_do_nothing(seconds)
        before = jack.xruns()
        demo.drag(points)
        out, err = client.communicate(timeout=seconds + 60)
        server = jack.xruns() - before
        if demo.quit() != 0:
            raise RuntimeError(f"the demo failed: {demo.demo.stderr.read().strip()[-300:]}")
    figures = json.loads(out)
    figures["server_xruns"] = server
    return figures


def run_demo(seconds: float, device: str, jack: Jack) -> dict:
    """The demo on JACK under Xvfb, dragged by xdotool for ``seconds``; its own --stats figures."""
    with tempfile.TemporaryDirectory() as folder:
        stats_path = Path(folder) / "stats.json"
        with _xvfb_demo()("--device", f"audio:{device}", "--profile", "sim-plate", "--stats", str(stats_path)) as demo:
            points = _drag_ready(demo, seconds)
            steps = len(points)
            before = jack.xruns()
            started = time.perf_counter()
            demo.drag(points)
            dragged_s = time.perf_counter() - started
            server = jack.xruns() - before
            if demo.quit() != 0:
                raise RuntimeError(f"the demo failed: {demo.demo.stderr.read().strip()[-300:]}")
        stats = json.loads(stats_path.read_text())
    return {"callbacks": stats["blocks_rendered"], "xruns": stats["underruns"] - stats["underruns_at_first_touch"],
            "server_xruns": server, "p50_us": stats["block_p50_us"], "p99_us": stats["block_p99_us"],
            "priority": f"{stats['priority']}; drag {dragged_s:.1f} s at {steps / dragged_s:.0f} Hz",
            "seconds": dragged_s}


def system_context() -> str:
    """What shapes wake-up latency here: the transparent huge page mode and the idle driver."""
    def read(path: str) -> str:
        try:
            return Path(path).read_text().strip()
        except OSError:
            return "unknown"
    return (f"transparent huge pages: {read('/sys/kernel/mm/transparent_hugepage/enabled')}; "
            f"cpuidle: {read('/sys/devices/system/cpu/cpuidle/current_driver')}; kernel {os.uname().release}")


def print_totals(totals: dict) -> None:
    """Each case's runs added up: xruns over minutes, the engine's beside the do-nothing client's (and with
    ``--demo``, beside the do-nothing client's while the demo's UI is dragged on the null device)."""
    print("\nAdded up over the runs of each case (client-side xruns):")
    for (period, hog), cases in totals.items():
        rates = {kind: c["xruns"] / c["minutes"] for kind, c in cases.items() if c["runs"]}
        counts = "; ".join(f"{kind} {c['xruns']} in {c['minutes']:.2f} min ({rates[kind]:.1f}/min)"
                           for kind, c in cases.items() if c["runs"])
        within = "yes" if rates["engine"] <= rates["do-nothing"] else "no"
        print(f"{period:4} frames, {'with' if hog else 'no'} hog, {cases['engine']['runs']} runs each: {counts}. "
              f"Engine within the do-nothing client's count: {within}"
              + (f"; within its count beside the UI: {'yes' if rates['engine'] <= rates[BESIDE_UI] else 'no'}"
                 if BESIDE_UI in rates else ""))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--periods", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--repeat", type=int, default=1, help="runs of each client in each case, taking turns")
    parser.add_argument("--ui-cmd", help="a shell command to run beside the engine as the UI's load")
    parser.add_argument("--demo", action="store_true", help="measure the demo's engine under Xvfb, dragged by xdotool")
    args = parser.parse_args()
    missing = [tool for tool in ("jackd", "jack_lsp") if shutil.which(tool) is None]
    if missing:
        print(f"bench_jack: missing {', '.join(missing)}; on Debian: sudo apt-get install jackd2")
        sys.exit(1)
    print(system_context())
    print(f"{'period':>6} {'hog':>4} {'client':>10} {'blocks':>8} {'p50 µs':>8} {'p99 µs':>8} "
          f"{'xruns/min client':>17} {'server':>7}  priority")
    totals: dict = {}
    for period in args.periods:
        jack = Jack(period)
        try:
            device = jack_device()
            for hog in (False, True):
                hogger = subprocess.Popen(HOG) if hog else None
                case = totals.setdefault((period, hog), {kind: {"xruns": 0, "minutes": 0.0, "runs": 0}
                                                         for kind in ("do-nothing", BESIDE_UI, "engine")})
                clients = ("do-nothing", BESIDE_UI, "demo") if args.demo else ("do-nothing", "engine")
                try:
                    for name in clients * max(1, args.repeat):
                        if name == "do-nothing":
                            figures = run_do_nothing(args.seconds, jack)
                        elif name == BESIDE_UI:
                            figures = run_do_nothing_beside_demo(args.seconds, jack)
                        elif name == "demo":
                            figures = run_demo(args.seconds, device, jack)
                        else:
                            figures = run_engine(args.seconds, device, args.ui_cmd, jack)
                        minutes = figures.get("seconds", args.seconds) / 60  # a loaded xdotool drags slower
                        added = case[name if name in ("do-nothing", BESIDE_UI) else "engine"]
                        added["xruns"] += figures["xruns"]
                        added["minutes"] += minutes
                        added["runs"] += 1
                        print(f"{period:6} {'yes' if hog else 'no':>4} {name:>10} {figures['callbacks']:8} "
                              f"{figures['p50_us']:8.1f} {figures['p99_us']:8.1f} "
                              f"{figures['xruns'] / minutes:17.1f} {figures['server_xruns'] / minutes:7.1f}  "
                              f"{figures.get('priority', '')}", flush=True)
                finally:
                    if hogger is not None:
                        hogger.terminate()
                        hogger.wait()
        finally:
            jack.stop()
    if args.repeat > 1:
        print_totals(totals)
    print(f"({args.seconds:g} s each at {RATE} Hz; jackd {'realtime' if jack.realtime else 'not realtime'}; "
          f"{os.cpu_count()} cores; server xruns are its log's XRun lines per minute of the run)")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
