"""A custom device: anything with ``signal``, ``rate_hz``, ``start(source)``, ``stop()`` and ``status()``.

This one takes the drive envelope (µm peak-to-peak at 12 kHz, as a plate driver that makes its own
carrier would), puts it behind the drive limiter as every device does, and logs it to CSV.
Run: python examples/custom_device.py
"""

import numpy as np

import ultraglide


class CsvPlate:
    signal, rate_hz = "control", 12000

    def __init__(self, path, profile):
        self.path, self.profile, self.samples = path, profile, []

    def start(self, source):  # a real device would pull from its own thread, at the plate's pace
        stage = ultraglide.output_stage(source, self.profile, self.signal, self.rate_hz)
        while not stage.finished:
            self.samples.append(stage.pull(120, None))              # 10 ms blocks

    def stop(self):
        np.savetxt(self.path, np.concatenate(self.samples), fmt="%.5f", header="drive_um_pp", comments="")

    def status(self):
        return {"device": "csv", "samples": sum(map(len, self.samples))}


profile = ultraglide.load_profile("sim-plate")
swipe = ultraglide.SwipePath("straight", speed_mm_s=80.0, duration_s=0.5, start_mm=(10.0, 24.0))
renderer = ultraglide.Renderer(ultraglide.resolve_texture("dots"), ultraglide.ExponentialModel(), profile,
                               trajectory=swipe)
device = CsvPlate("envelope.csv", profile)
device.start(ultraglide.EnvelopeSource(renderer))
device.stop()
print(device.status())
