"""One's own touch source driving a device in real time, through the engine (its own process).

The finger circles, reported at 120 Hz as a touch panel would; the device here is ``wav:touch.wav``
(records in real time what a plate would get). Use ``sim``, ``serial:/dev/ttyACM0`` or ``audio`` for a
plate. Run: python examples/touch_source.py
"""

import math
import time

import ultraglide

config = ultraglide.EngineConfig(texture="grating-2mm", model="exponential", device="wav:touch.wav")
with ultraglide.Engine.start(config) as engine:                  # renderer and device in their own process
    engine.wait_ready(60)
    start = time.perf_counter()
    for report in range(120):                                     # one second of a 120 Hz touch panel
        angle = 2 * math.pi * report / 120                         # a 20 mm circle, once a second
        engine.touch(time.perf_counter(), 40 + 10 * math.cos(angle), 25 + 10 * math.sin(angle), force_n=0.4)
        time.sleep(max(0.0, start + (report + 1) / 120 - time.perf_counter()))
    engine.touch(time.perf_counter(), 50.0, 25.0, down=False)    # the finger lifts
    print(engine.status().words())
# leaving the block ramps to rest, rests the device and ends the engine's process
