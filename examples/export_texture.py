"""Render a bundled texture along a swipe to a WAV file, in a few lines.

Run: python examples/export_texture.py   (writes grating.wav in the current directory)
"""

import ultraglide

result = ultraglide.export_wav(
    "grating-1mm",          # a library name, a texture file, or an image
    "grating.wav",
    speed_mm_s=100.0,       # a 1 mm grating at 100 mm/s: 100 Hz of friction modulation
    duration_s=2.0,
    model="exponential",    # Monnoyer et al. 2018; or "paper", "table:F.csv", "CAL.toml"
    profile="sim-plate",    # 25 kHz plate, 6 µm p-p limit
)
print(f"wrote {result.path}: {result.duration_s:.2f} s at {result.rate_hz} Hz, "
      f"carrier {result.carrier_hz:g} Hz, {result.clipped_samples} clipped samples")
