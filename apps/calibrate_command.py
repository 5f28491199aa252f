"""``ultraglide calibrate``: fit a model to measured points and write a calibration file."""

from __future__ import annotations

from pathlib import Path

from ultraglide.apps.atomic import atomic_path
from ultraglide.render.calibration import calibration_toml, fit_model
from ultraglide.render.measurements import read_measurements

POOR_FIT_RMS = 0.05


def run(args) -> int:
    data = read_measurements(args.data)
    fit = fit_model(data, args.model)
    print(f"fitted {fit.model.describe()}")
    for name, value in fit.model.parameters().items():
        print(f"  {name} = {value:.6g}" if isinstance(value, float) else f"  {name} = {value}")
    print(f"  {len(data)} points, rms residual {fit.rms_residual:.4f}, "
          f"largest {fit.max_abs_residual:.4f}")
    print("  amplitude µm p-p   force N   measured   model    residual")
    forces = data.force_n if data.force_n is not None else [None] * len(data)
    for a, r, f, e in zip(data.amplitude_um_pp, data.relative_friction, forces, fit.residuals,
                          strict=True):
        force = f"{f:7.3g}" if f is not None else "      -"
        print(f"  {a:16.2f}   {force}   {r:8.4f}   {r - e:7.4f}   {e:+8.4f}")
    if fit.rms_residual > POOR_FIT_RMS:
        print(f"warning: the {args.model} model does not follow these data well "
              f"(rms residual {fit.rms_residual:.3f}); consider --model exponential or table:FILE")
    with atomic_path(Path(args.output)) as temporary:
        temporary.write_text(calibration_toml(fit))
    print(f"wrote {args.output}")
    return 0
