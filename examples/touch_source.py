"""One's own touch source driving a device: finger reports pushed live, as a touch panel would.

The finger circles at 120 Hz of reports; the device here is ``wav:touch.wav`` (records in real time
what a plate would get). Use ``sim``, ``serial:/dev/ttyACM0`` or ``audio`` for a plate.
Run: python examples/touch_source.py
"""

import math
import time

import ultraglide

profile = ultraglide.load_profile("sim-plate")
renderer = ultraglide.Renderer(ultraglide.resolve_texture("grating-2mm"), ultraglide.load_model("exponential"),
                               profile)                           # no trajectory: it renders live reports
device = ultraglide.open_device("wav:touch.wav", profile)
device.start(ultraglide.renderer_source(device, renderer))
start = time.perf_counter()
try:
    for report in range(120):                                     # one second of a 120 Hz touch panel
        angle = 2 * math.pi * report / 120                         # a 20 mm circle, once a second
        renderer.push(time.perf_counter(), 40 + 10 * math.cos(angle), 25 + 10 * math.sin(angle), force_n=0.4)
        time.sleep(max(0.0, start + (report + 1) / 120 - time.perf_counter()))
    renderer.push(time.perf_counter(), 50.0, 25.0, down=False)    # the finger lifts
finally:
    device.stop()                                                 # ramps down, then rests the plate
print(device.status())
