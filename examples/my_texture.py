"""A procedural texture of one's own: concentric rings from numpy, saved as a texture file and rendered.

Run: python examples/my_texture.py   (writes rings.png and rings.wav in the current directory)
"""

import numpy as np

import ultraglide

width_mm, height_mm, px_per_mm = 60.0, 40.0, 20
x = (np.arange(int(width_mm * px_per_mm)) + 0.5) / px_per_mm         # pixel centres, mm
y = (np.arange(int(height_mm * px_per_mm)) + 0.5) / px_per_mm
radius_mm = np.hypot(*np.meshgrid(x - width_mm / 2, y - height_mm / 2))
rings = 0.5 + 0.5 * np.cos(2 * np.pi * radius_mm / 3.0)                # a ring every 3 mm
ratio = 0.3 + 0.7 * rings                                              # friction ratio 0.3 (slippery) .. 1 (at rest)

texture = ultraglide.Texture(ratio.astype(np.float32), width_mm, height_mm, outside="clamp",
                             name="rings", description="concentric rings every 3 mm")
ultraglide.save_texture(texture, "rings.png")                          # a 16-bit PNG any viewer opens
swipe = ultraglide.SwipePath("straight", speed_mm_s=120.0, duration_s=0.4, start_mm=(6.0, 20.0))
result = ultraglide.export_wav(ultraglide.load_texture("rings.png"), "rings.wav", swipe)
print(f"wrote rings.png ({texture.values.shape[1]}×{texture.values.shape[0]} px) and {result.path}")
