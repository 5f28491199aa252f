"""``ultraglide model``: the fingerprint physics at one normal force."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from ultraglide.apps.cli.options import add_model_option
from ultraglide.apps.cli.types import FORCE_N, ratio

if TYPE_CHECKING:
    from ultraglide.render.physics.fingerprint import FingerParams
    from ultraglide.render.physics.friction_models import FrictionModel
from ultraglide.apps.cli.errors import UsageError

CURVE_STEP_UM = 0.5
CURVE_END_UM = 10.0
EXAMPLE_DATA = Path(__file__).parent.parent / "data" / "monnoyer2018-fit.csv"


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide model``: its options."""
    model = commands.add_parser(
        "model", help="the fingerprint physics at one normal force",
        description="Contact area, ridge stiffness, detachment amplitude, glide threshold and "
                    "relative friction against amplitude, from the paper's model.")
    model.add_argument("--force", type=FORCE_N, default=None, metavar="N",
                       help="normal force of the finger, N (default: 0.5; figures: the paper's force for each)")
    add_model_option(model)
    model.add_argument("--ratio", type=ratio, metavar="R",
                       help="also give the amplitude that yields friction ratio R")
    model.add_argument("--json", action="store_true", help="print one JSON object")
    model.add_argument("--plots", metavar="DIR",
                       help="write the paper's figures 2-9 here, each as a 300 dpi PNG and a PDF")
    model.add_argument("--report", metavar="FILE.pdf",
                       help="write one page on the model at this force: parameters, curve, inverse, contact")
    model.add_argument("--data", metavar="CSV",
                       help="measured points for figure 9 (default: the bundled Monnoyer 2018 fit)")
    model.set_defaults(run=run)


def _finger(model: FrictionModel) -> FingerParams:
    """The ridge model's parameters: the model's own for the paper model, else the paper's Table I."""
    from ultraglide.render.physics.fingerprint import FingerParams
    from ultraglide.render.physics.friction_models import PaperModel

    return model.params if isinstance(model, PaperModel) else FingerParams()


def summary(force_n: float, model: FrictionModel | str, ratio: float | None) -> dict:
    """Everything ``ultraglide model`` reports, as plain JSON-able values."""
    import numpy as np
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.fingerprint import (
        contact_area_mm2,
        detach_amplitude_um_pp,
        glide_threshold_um_pp,
        normal_stiffness_n_per_m,
        tangential_stiffness_n_per_m,
    )

    model = load_model(model) if isinstance(model, str) else model
    params = _finger(model)
    amplitude = np.arange(0.0, CURVE_END_UM + 1e-9, CURVE_STEP_UM)
    curve = model.relative_friction(amplitude, force_n)
    result = {
        "force_n": force_n,
        "model": model.describe(),
        "contact_area_mm2": float(contact_area_mm2(force_n, params)),
        "normal_stiffness_n_per_m": float(normal_stiffness_n_per_m(force_n, params)),
        "tangential_stiffness_n_per_m": float(tangential_stiffness_n_per_m(force_n, params)),
        "detach_amplitude_um_pp": float(detach_amplitude_um_pp(force_n, params)),
        "glide_threshold_um_pp": float(glide_threshold_um_pp(force_n, params)),
        "curve": [[float(a), round(float(r), 6)] for a, r in zip(amplitude, curve, strict=True)],
    }
    if ratio is not None:
        inversion = model.amplitude_um_pp(ratio, force_n)
        result["ratio"] = ratio
        result["amplitude_for_ratio_um_pp"] = float(inversion.amplitude_um_pp)
        result["ratio_reachable"] = inversion.clamped == 0
        result["lowest_reachable_ratio"] = float(model.floor_ratio(force_n))
    return result


def format_text(result: dict) -> str:
    from ultraglide.render.physics.friction_models import CEILING_UM_PP

    lines = [
        f"Finger at {result['force_n']:g} N  (model: {result['model']})",
        f"  contact area          {result['contact_area_mm2']:10.2f} mm²      eq. (3)",
        f"  normal stiffness      {result['normal_stiffness_n_per_m']:10.4g} N/m      eq. (1)",
        f"  tangential stiffness  {result['tangential_stiffness_n_per_m']:10.4g} N/m      eq. (2)",
        f"  detach amplitude      {result['detach_amplitude_um_pp']:10.2f} µm p-p   eq. (6)",
        f"  glide threshold       {result['glide_threshold_um_pp']:10.2f} µm p-p   eq. (5)",
        "",
        "  amplitude µm p-p   relative friction",
    ]
    lines += [f"  {a:16.1f}   {r:17.3f}" for a, r in result["curve"][::2]]
    if "ratio" in result:
        lines.append("")
        if result["ratio_reachable"]:
            lines.append(f"  ratio {result['ratio']:g} needs {result['amplitude_for_ratio_um_pp']:.3f} µm p-p")
        else:
            lines.append(
                f"  ratio {result['ratio']:g} is out of reach: the lowest this model gives within "
                f"{CEILING_UM_PP:g} µm is {result['lowest_reachable_ratio']:.3f} "
                f"(clamped to {result['amplitude_for_ratio_um_pp']:.2f} µm p-p)"
            )
    return "\n".join(lines)


def run(args) -> int:
    from ultraglide.render.physics.calibration import load_model
    from ultraglide.render.physics.friction_models import DEFAULT_FORCE_N

    force = DEFAULT_FORCE_N if args.force is None else args.force
    if args.report and Path(args.report).suffix.lower() not in (".pdf", ".svg", ".png"):
        raise UsageError(f"{args.report}: the report is a .pdf (or .svg, or .png at 300 dpi)")
    model = load_model(args.model)
    result = summary(force, model, args.ratio)
    if args.plots:
        from ultraglide.apps.figures.paper import write_paper_figures

        data = Path(args.data) if args.data else EXAMPLE_DATA
        written = write_paper_figures(Path(args.plots), data, _finger(model), args.force, model)
        result["plots"] = [str(path) for path in written]
    if args.report:
        from ultraglide.apps.figures.model_report import write_report

        result["plots"] = result.get("plots", []) + [str(p) for p in write_report(Path(args.report), model, result,
                                                                                  _finger(model))]
    if args.json:
        print(json.dumps(result))
    else:
        print(format_text(result))
        for path in result.get("plots", []):
            print(f"wrote {path}")
    return 0
