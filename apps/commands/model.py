"""``ultraglide model``: the fingerprint physics at one normal force."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import add_figure_width_option, add_model_option, output_option, refuse_ignored
from ultraglide.apps.cli.output import print_json
from ultraglide.apps.cli.types import CARRIER_HZ, FORCE_N, PRELOAD_N, Bounded, ratio
from ultraglide.apps.figures import PAPER_FIGURES, both_formats

if TYPE_CHECKING:
    from ultraglide.render.physics.fingerprint import FingerParams
    from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.files import model_file, refuse_overlaps

CURVE_STEP_UM = 0.5
CURVE_END_UM = 10.0
EXAMPLE_DATA = Path(__file__).parent.parent / "data" / "monnoyer2018-fit.csv"
DYNAMICS_SPEEDS_MM_S = (50.0, 100.0, 200.0)
DYNAMICS_LIMIT_UM_PP = 6.0  # the grating's trough: the floor within a typical plate's limit (sim-plate's)
DYNAMICS_FIGURES = ("friction-in-time", "contrast-transfer")
SPEED_FIGURES = ("speed-law",)
SLIDING_SPEED = Bounded(0.0, 2000.0, "mm/s", what="sliding speed")


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide model``: its options."""
    model = commands.add_parser(
        "model", help="the fingerprint physics at one normal force",
        description="A friction model at one normal force: its force law and where it holds, relative friction "
                    "against amplitude, and, for the models built on the paper's ridges (paper, paper-uniform, "
                    "squeeze-film), contact area, ridge stiffness, detachment amplitude, glide threshold and the "
                    "ridge layer's shear resonance.")
    model.add_argument("--force", type=FORCE_N, default=None, metavar="N",
                       help="normal force of the finger, N (default: 0.5; figures: the paper's force for each)")
    add_model_option(model)
    model.add_argument("--ratio", type=ratio, metavar="R",
                       help="also give the amplitude that yields friction ratio R")
    model.add_argument("--speed-mm-s", type=SLIDING_SPEED, metavar="V",
                       help="the finger's sliding speed, mm/s: the curve, the floor and --ratio's amplitude at it, "
                            "through the model's speed law (speed:S:NAME; a model without one: no dependence; "
                            "default: the law's reference speed)")
    model.add_argument("--json", action="store_true", help="print one JSON object")
    output_option(model, "--plots", kind="folder",
                  also=both_formats(PAPER_FIGURES + DYNAMICS_FIGURES + SPEED_FIGURES),
                  metavar="DIR", help="write the paper's figures 2-9 here, each as a 300 dpi PNG and a PDF (and, for a "
                                      "dynamic model, friction-in-time and contrast-transfer; for a model with a "
                                      "speed law, speed-law)")
    output_option(model, "--report", metavar="FILE.pdf",
                       help="write one page on the model at this force: parameters, curve, inverse, contact")
    model.add_argument("--data", metavar="CSV",
                       help="measured points for figure 9 (default: the bundled Monnoyer 2018 fit)")
    model.add_argument("--preload-n", type=PRELOAD_N, default=0.0, metavar="T",
                       help="tangential preload the finger holds on a lateral vibrator, N, for the glide threshold "
                            "(default: 0, the paper's eq. 5; the paper's psychophysics needs about 0.1 N at 0.4 N)")
    model.add_argument("--carrier-hz", type=CARRIER_HZ, metavar="F",
                       help="lateral vibration frequency to check the quasi-static glide threshold against the ridge "
                            "layer's shear resonance (a warning when it fails there)")
    add_figure_width_option(model)
    model.set_defaults(run=run)


def _finger(model: FrictionModel) -> FingerParams | None:
    """The ridge model's parameters of a model built on the paper's ridges, else None."""
    from ultraglide.render.physics.friction_models import PaperModel
    from ultraglide.render.physics.speed_law import SpeedLawModel
    from ultraglide.render.physics.squeeze_film import SqueezeFilmModel

    model = model.static if isinstance(model, SpeedLawModel) else model  # the ridges are the static model's
    if isinstance(model, PaperModel):
        return model.params
    if isinstance(model, SqueezeFilmModel):
        return model.finger
    return None


def summary(force_n: float, model: FrictionModel | str, ratio: float | None, preload_n: float = 0.0,
            carrier_hz: float | None = None, speed_mm_s: float | None = None) -> dict:
    """Everything ``ultraglide model`` reports, as plain JSON-able values: what the chosen model has; at a sliding
    speed (mm/s) where one is given, through the model's speed law (none: the same as without)."""
    import numpy as np
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.fingerprint import (
        contact_area_mm2,
        detach_amplitude_um_pp,
        dynamic_stiffness_ratio,
        glide_threshold_um_pp,
        normal_stiffness_n_per_m,
        quasi_static_limit_hz,
        quasi_static_warning,
        ridge_shear_resonance_hz,
        tangential_stiffness_n_per_m,
    )
    from ultraglide.render.physics.speed_law import scaled_inverse, speed_law_of

    model = load_model(model) if isinstance(model, str) else model
    params = _finger(model)
    law = speed_law_of(model)

    def scale_at(speed: float | None) -> float:  # the amplitude a ratio needs at this speed over the model's
        return 1.0 if law is None or speed is None else law.one_scale(speed)

    scale = scale_at(speed_mm_s)
    amplitude = np.arange(0.0, CURVE_END_UM + 1e-9, CURVE_STEP_UM)
    curve = model.relative_friction(amplitude / scale, force_n)  # the static model at a_eff = a / k(v)
    low, high = model.valid_force_range_n()
    result = {
        "force_n": force_n,
        "model": model.describe(),
        "force_law": model.force_law(),
        "valid_force_range_n": [low, high],
    }
    if speed_mm_s is not None:
        result["speed_mm_s"] = speed_mm_s
        result["speed_law"] = (law.describe() if law is not None else "no dependence on sliding speed (s = 0)")
        result["amplitude_scale"] = scale
    if params is not None:
        result.update({
            "contact_area_mm2": float(contact_area_mm2(force_n, params)),
            "normal_stiffness_n_per_m": float(normal_stiffness_n_per_m(force_n, params)),
            "tangential_stiffness_n_per_m": float(tangential_stiffness_n_per_m(force_n, params)),
            "detach_amplitude_um_pp": float(detach_amplitude_um_pp(force_n, params)),
            "glide_threshold_um_pp": float(glide_threshold_um_pp(force_n, params)),
            "preload_n": preload_n,
            "glide_threshold_with_preload_um_pp": float(glide_threshold_um_pp(force_n, params, preload_n)),
            "ridge_shear_resonance_hz": ridge_shear_resonance_hz(params),
            "ridge_shear_resonance_lumped_hz": ridge_shear_resonance_hz(params, lumped=True),
            "quasi_static_limit_hz": quasi_static_limit_hz(params),
        })
        if carrier_hz is not None:
            result["carrier_hz"] = carrier_hz
            result["dynamic_stiffness_ratio"] = float(dynamic_stiffness_ratio(carrier_hz, params))
            problem = quasi_static_warning(carrier_hz, params)
            if problem:
                result["quasi_static_warning"] = problem
    dynamics = getattr(model, "dynamics", None)
    if dynamics is not None:
        from ultraglide.render.planning import contrast_transfer

        floor = float(model.floor_ratio(force_n, DYNAMICS_LIMIT_UM_PP / scale))
        floors = {v: float(model.floor_ratio(force_n, DYNAMICS_LIMIT_UM_PP / scale_at(v)))
                  for v in DYNAMICS_SPEEDS_MM_S}
        result["dynamics"] = {
            **dynamics.parameters(),
            "words": dynamics.describe(),
            "recovery_s_at_mm_s": {f"{v:g}": float(dynamics.recovery_at_s(v)) for v in DYNAMICS_SPEEDS_MM_S},
            "grating_1mm": [{"speed_mm_s": v, "floor_at_limit": floors[v],
                             **_kept(contrast_transfer(dynamics, 1.0, v, floors[v]))} for v in DYNAMICS_SPEEDS_MM_S],
            "floor_at_limit": floor,
            "limit_um_pp": DYNAMICS_LIMIT_UM_PP,
        }
    result["curve"] = [[float(a), round(float(r), 6)] for a, r in zip(amplitude, curve, strict=True)]
    ceiling = model.max_amplitude_um_pp  # the model's own range of amplitudes, at the speed asked
    if ratio is not None or speed_mm_s is not None:  # the floor within it, at that speed
        result["amplitude_ceiling_um_pp"] = ceiling
        result["lowest_reachable_ratio"] = float(model.floor_ratio(force_n, ceiling / scale))
    if ratio is not None:
        inversion = scaled_inverse(model, ratio, force_n, ceiling, scale)
        result["ratio"] = ratio
        result["amplitude_for_ratio_um_pp"] = float(inversion.amplitude_um_pp)
        result["ratio_reachable"] = inversion.clamped == 0
    return result


def _kept(kept) -> dict:
    return {"contrast_instantaneous": round(kept.instantaneous, 4), "contrast_planned": round(kept.planned, 4),
            "rms_instantaneous": round(kept.instantaneous_rms, 4), "rms_planned": round(kept.planned_rms, 4)}


def format_text(result: dict) -> str:
    from ultraglide.render.physics.speed_law import FASTEST_SPEED_MM_S, SLOWEST_SPEED_MM_S

    low, high = result["valid_force_range_n"]
    at = f"{result['speed_mm_s']:g} mm/s" if "speed_mm_s" in result else ""
    if at and not SLOWEST_SPEED_MM_S <= result["speed_mm_s"] <= FASTEST_SPEED_MM_S:  # where the law holds it
        held = SLOWEST_SPEED_MM_S if result["speed_mm_s"] < SLOWEST_SPEED_MM_S else FASTEST_SPEED_MM_S
        at += f" (held at {held:g} mm/s)"
    speed = f" sliding at {at}" if at else ""
    lines = [
        f"Finger at {result['force_n']:g} N{speed}  (model: {result['model']})",
        f"  force law: {result['force_law']}; holds on {low:.3g}-{high:.3g} N",
    ]
    if speed:
        lines.append(f"  speed law: {result['speed_law']}; at {at} a ratio needs "
                     f"{result['amplitude_scale']:.3g} x the amplitude it needs at the reference")
        lines.append(f"  lowest friction within {result['amplitude_ceiling_um_pp']:g} µm p-p at {at}: "
                     f"{result['lowest_reachable_ratio']:.3f}")
    if "contact_area_mm2" in result:
        lines += [
            f"  contact area          {result['contact_area_mm2']:10.2f} mm²      eq. (3), at most a fingertip's",
            f"  normal stiffness      {result['normal_stiffness_n_per_m']:10.4g} N/m      eq. (1)",
            f"  tangential stiffness  {result['tangential_stiffness_n_per_m']:10.4g} N/m      eq. (2)",
            f"  detach amplitude      {result['detach_amplitude_um_pp']:10.2f} µm p-p   eq. (6)",
            f"  glide threshold       {result['glide_threshold_um_pp']:10.2f} µm p-p   eq. (5), no tangential preload",
        ]
        if result["preload_n"]:
            lines.append(f"  glide threshold       {result['glide_threshold_with_preload_um_pp']:10.2f} µm p-p   "
                         f"with a {result['preload_n']:g} N tangential preload")
        lines.append(f"  ridge shear resonance {result['ridge_shear_resonance_hz'] / 1e3:10.1f} kHz      from rho "
                     f"(lumped estimate {result['ridge_shear_resonance_lumped_hz'] / 1e3:.1f} kHz); the lateral "
                     f"analysis is quasi-static within 10 % below {result['quasi_static_limit_hz'] / 1e3:.1f} kHz")
        if "carrier_hz" in result:
            lines.append(f"  at {result['carrier_hz'] / 1e3:g} kHz the ridges' dynamic stiffness is "
                         f"{result['dynamic_stiffness_ratio']:.2f} of k_t")
    if "dynamics" in result:
        d = result["dynamics"]
        lines += ["", f"  friction in time: {d['words']}",
                  f"  a 1 mm grating (1 down to {d['floor_at_limit']:.2f}, the floor within {d['limit_um_pp']:g} µm), "
                  f"felt contrast and RMS error (ours):"]
        if len({g["floor_at_limit"] for g in d["grating_1mm"]}) > 1:
            lines.append("    (the floor rises with speed: " + ", ".join(
                f"{g['floor_at_limit']:.2f} at {g['speed_mm_s']:g} mm/s" for g in d["grating_1mm"]) + ")")
        lines += [f"    {g['speed_mm_s']:5g} mm/s: instantaneous {100 * g['contrast_instantaneous']:3.0f} % "
                  f"(error {g['rms_instantaneous']:.3f}), planned {100 * g['contrast_planned']:3.0f} % "
                  f"(error {g['rms_planned']:.3f})" for g in d["grating_1mm"]]
    lines += ["", "  amplitude µm p-p   relative friction"]
    lines += [f"  {a:16.1f}   {r:17.3f}" for a, r in result["curve"][::2]]
    if "ratio" in result:
        lines.append("")
        if result["ratio_reachable"]:
            lines.append(f"  ratio {result['ratio']:g} needs {result['amplitude_for_ratio_um_pp']:.3f} µm p-p")
        else:
            lines.append(
                f"  ratio {result['ratio']:g} is out of reach: the lowest this model gives within "
                f"{result['amplitude_ceiling_um_pp']:g} µm is {result['lowest_reachable_ratio']:.3f} "
                f"(clamped to {result['amplitude_for_ratio_um_pp']:.2f} µm p-p)"
            )
    return "\n".join(lines)


def run(args) -> int:
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.friction_models import DEFAULT_FORCE_N

    force = DEFAULT_FORCE_N if args.force is None else args.force
    if args.report and Path(args.report).suffix.lower() not in (".pdf", ".svg", ".png"):
        raise UsageError(f"{args.report}: the report is a .pdf (or .svg, or .png at 300 dpi)")
    if args.data and not args.plots:
        raise UsageError("--data holds the measured points of figure 9, drawn only with --plots DIR: add --plots DIR "
                         "(to fit a model to measured points: ultraglide calibrate DATA.csv)")
    if not (args.plots or args.report):
        refuse_ignored(args, {"figure_width": "column"}, "{option} lays figures out: give --plots DIR or --report "
                                                         "FILE.pdf, or leave it out")
    refuse_overlaps({"--report": args.report}, {"--model": model_file(args.model), "--data": args.data})
    model = load_model(args.model)
    params = _finger(model)
    if args.preload_n and params is not None and not args.preload_n < params.static_friction * force:
        raise UsageError(f"--preload-n {args.preload_n:g} N is gross slip already at {force:g} N: it must be below "
                         f"mu_s F = {params.static_friction * force:g} N")
    result = summary(force, model, args.ratio, args.preload_n, args.carrier_hz, args.speed_mm_s)
    if args.plots:
        from ultraglide.apps.figures.paper import write_paper_figures

        data = Path(args.data) if args.data else EXAMPLE_DATA
        from ultraglide.render.physics.fingerprint import FingerParams

        written = write_paper_figures(Path(args.plots), data, params or FingerParams(), args.force, model,
                                      args.figure_width)
        if "dynamics" in result:
            from ultraglide.apps.figures.dynamics import contrast_figure, friction_in_time

            floor = result["dynamics"]["floor_at_limit"]
            written.append(friction_in_time(Path(args.plots) / "friction-in-time.png", model.dynamics, floor,
                                            args.figure_width)[0])
            written.append(contrast_figure(Path(args.plots) / "contrast-transfer.png", model.dynamics, floor,
                                           args.figure_width)[0])
        from ultraglide.render.physics.speed_law import speed_law_of

        if speed_law_of(model) is not None:
            from ultraglide.apps.figures.speed_law import speed_figure

            written += speed_figure(Path(args.plots) / "speed-law.png", model, force, DYNAMICS_LIMIT_UM_PP,
                                    args.figure_width)[:1]
        result["plots"] = [str(path) for path in written]
    if args.report:
        from ultraglide.apps.figures.model_report import write_report

        result["plots"] = result.get("plots", []) + [str(p) for p in write_report(Path(args.report), model, result,
                                                                                  params, args.figure_width)]
    if "quasi_static_warning" in result:
        print(f"warning: {result['quasi_static_warning']}", file=sys.stderr)
    if args.json:
        print_json(result)
    else:
        print(format_text(result))
        for path in result.get("plots", []):
            print(f"wrote {path}")
    return 0
