"""Calibrate a friction model from measured points (CSV), save it, and render with it.

Run: python examples/calibrate_and_render.py   (writes measured.csv, finger.toml and calibrated.wav)
"""

import numpy as np

import ultraglide

# Stand-in measurements: relative friction against amplitude (µm peak-to-peak) at two forces, with noise.
rng = np.random.default_rng(1)
amplitude = np.tile(np.linspace(0.0, 5.0, 11), 2)
force = np.repeat([0.3, 0.6], 11)
friction = np.exp(-((amplitude / 2) / 1.2) ** 2 / 2) + rng.normal(0, 0.01, amplitude.size)
rows = "\n".join(f"{a:.3f},{f:.4f},{n}" for a, f, n in zip(amplitude, friction, force, strict=True))
with open("measured.csv", "w") as stream:
    stream.write("amplitude_um_pp,relative_friction,force_n\n" + rows + "\n")

fit = ultraglide.fit_model(ultraglide.read_measurements("measured.csv"), "exponential")
with open("finger.toml", "w") as stream:
    stream.write(ultraglide.calibration_toml(fit))             # a file every command accepts as --model
model = ultraglide.read_calibration("finger.toml")
print(model.describe())
print(f"half the friction needs {float(model.amplitude_um_pp(0.5, 0.5).amplitude_um_pp):.2f} µm p-p")
result = ultraglide.export_wav("checkerboard-5mm", "calibrated.wav", model=model, duration_s=1.0)
print(f"wrote {result.path}")
