"""The simulated finger's options, shared by ``plate-sim`` and the commands that run the in-process ``sim``."""

from __future__ import annotations

import argparse

from ultraglide.apps.cli.options import output_option
from ultraglide.apps.cli.types import SEED, Bounded

FRACTION = Bounded(0.0, 0.9, what="fraction")
MOISTURE = Bounded(0.0, 2.0, what="fraction")
PERIOD_S = Bounded(0.1, 3600.0, "s")
LAW_SCALE = Bounded(0.1, 10.0)
FLOOR = Bounded(0.0, 1.0, high_open=True)
MU0 = Bounded(0.05, 5.0)
FINGER_SPEED = Bounded(0.0, 2000.0, "mm/s")
NOISE_N = Bounded(0.0, 1.0, "N")
BANDWIDTH_HZ = Bounded(0.0, 20000.0, "Hz")
DELAY_MS = Bounded(0.0, 100.0, "ms")
LOG_HZ = Bounded(1.0, 48000.0, "Hz")


def add_finger_options(parser: argparse.ArgumentParser, where: str) -> None:
    """The ``--finger*`` options, in a group saying ``where`` they apply."""
    group = parser.add_argument_group(f"the simulated finger ({where})")
    group.add_argument("--finger", metavar="LAW",
                       help="a finger on the plate, with force sensors under it: its friction law, any model the "
                            "host takes (exponential, stretched, paper, table:FILE.csv with amplitude_um_pp,"
                            "relative_friction,force_n, CAL.toml), or default: the host default's static law with its "
                            "scale x0.7 and a floor of 0.1, unlike the host's model")
    group.add_argument("--finger-scale", type=LAW_SCALE, metavar="K",
                       help="stretch the law's amplitude axis by K (default: 0.7 for the default law, else 1)")
    group.add_argument("--finger-floor", type=FLOOR, metavar="D",
                       help="friction vibration does not remove, a share of friction at rest (default: 0.1 for "
                            "the default law, else 0)")
    group.add_argument("--finger-mu0", type=MU0, metavar="MU0",
                       help="its friction coefficient at rest (default: 1)")
    group.add_argument("--finger-drift", type=FRACTION, metavar="FRACTION",
                       help="the law's scale swings by ±FRACTION (default: 0.3)")
    group.add_argument("--finger-drift-period-s", type=PERIOD_S, metavar="S",
                       help="over this period (default: 60)")
    group.add_argument("--finger-moisture", type=MOISTURE, metavar="FRACTION",
                       help="friction at rest rises by FRACTION after a long dwell (default: 0.25)")
    group.add_argument("--finger-moisture-tau-s", type=PERIOD_S, metavar="S",
                       help="the dwell's time constant (default: 20)")
    group.add_argument("--finger-force", metavar="SPEC",
                       help="its normal force: N (constant), walk (a random walk in 0.2-1 N), walk:LOW-HIGH, or "
                            "a CSV t_s,force_n[,speed_mm_s] (0 N: lifted) (default: walk)")
    group.add_argument("--finger-speed-mm-s", type=FINGER_SPEED, metavar="V",
                       help="its sliding speed; 0: at rest, no friction to measure (default: 100)")
    group.add_argument("--finger-noise-n", type=NOISE_N, metavar="N",
                       help="the force sensors' noise, N rms a sample (default: 0.005)")
    group.add_argument("--finger-bandwidth-hz", type=BANDWIDTH_HZ, metavar="HZ",
                       help="the force sensors' bandwidth, 0 for none (default: 300)")
    group.add_argument("--finger-delay-ms", type=DELAY_MS, metavar="MS",
                       help="the force sensors' delay (default: 1)")
    output_option(group, "--finger-log", kind="log", metavar="FILE.csv",
                       help="write the finger's true state as it goes: t_s,amplitude_um_pp,normal_force_n,"
                            "relative_friction,sliding (t_s on the host's perf_counter clock)")
    group.add_argument("--finger-log-hz", type=LOG_HZ, metavar="HZ",
                       help="the log's rows a second, up to the plate's 48000 (default: 2000)")
    group.add_argument("--finger-fault", action="append", type=_fault, metavar="KIND:START-END",
                       help="the force sensors misread from START to END s after the plate started: nan, range "
                            "(50 N) or zero (a cut cable); repeat for several")
    group.add_argument("--finger-seed", type=SEED, metavar="N", help="its random walk's seed (default: 0)")
    group.add_argument("--finger-dynamics", action=argparse.BooleanOptionalAction, default=None,
                       help="its friction lags the law as measured fingers' do: 5 ms to fall when the vibration "
                            "starts, 70 ms to recover at 22 mm/s, slower when sliding slower (Meyer et al. 2014; on "
                            "for the default finger and a dynamic law; --no-finger-dynamics: it follows at once)")


def _fault(text: str) -> str:
    from ultraglide.devices.errors import DeviceError
    from ultraglide.devices.sim.finger import SensorFault

    try:
        SensorFault.parse(text)
    except DeviceError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


FIELDS = {"finger": "law", "finger_scale": "scale", "finger_floor": "floor", "finger_mu0": "mu0",
          "finger_drift": "drift", "finger_drift_period_s": "drift_period_s", "finger_moisture": "moisture",
          "finger_moisture_tau_s": "moisture_tau_s", "finger_force": "force", "finger_speed_mm_s": "speed_mm_s",
          "finger_noise_n": "noise_n", "finger_bandwidth_hz": "bandwidth_hz", "finger_delay_ms": "delay_ms",
          "finger_log": "log", "finger_seed": "seed", "finger_log_hz": "log_hz", "finger_fault": "faults",
          "finger_dynamics": "dynamics"}


def finger_asked(args) -> bool:
    """Whether any ``--finger*`` option was given."""
    return any(getattr(args, name, None) is not None for name in FIELDS)


def finger_config(args, wanted: bool = False):
    """The :class:`~ultraglide.render.engine.finger_setup.FingerConfig` the options describe (the defaults for
    those not given), or None when no finger option was given and ``wanted`` is false (``wanted``: the default
    finger anyway, e.g. for the closed loop on the simulator)."""
    from ultraglide.render.engine.finger_setup import FingerConfig

    if not (wanted or finger_asked(args)):
        return None
    given = {field: getattr(args, name) for name, field in FIELDS.items() if getattr(args, name, None) is not None}
    if "log_hz" in given and "log" not in given:
        from ultraglide.apps.cli.errors import UsageError

        raise UsageError("--finger-log-hz is the rate of --finger-log's rows: add --finger-log FILE.csv, or leave it "
                         "out")
    if "faults" in given:
        given["faults"] = tuple(given["faults"])
    return FingerConfig(**given)
