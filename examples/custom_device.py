"""A custom device: anything with ``signal``, ``rate_hz``, ``start(source)``, ``stop()`` and ``status()``.

This one pulls the drive envelope (µm peak-to-peak at the control rate, as a plate driver making its
own carrier would) on its own thread and logs it to CSV. Run: python examples/custom_device.py
"""

import threading

import numpy as np

import ultraglide


class CsvPlate:
    signal, rate_hz, block = "control", 12000, 120               # 10 ms blocks of envelope at 12 kHz

    def __init__(self, path):
        self.stream, self.pulled = open(path, "w"), 0
        self.stream.write("drive_um_pp\n")

    def start(self, source):
        self.thread = threading.Thread(target=self._run, args=(source,))
        self.thread.start()

    def _run(self, source):                                       # faster than real time: an offline path
        while not source.finished:
            np.savetxt(self.stream, source.pull(self.block, None), fmt="%.5f")
            self.pulled += self.block

    def stop(self):
        self.thread.join()
        self.stream.close()

    def status(self):
        return {"device": "csv", "samples": self.pulled}


texture = ultraglide.resolve_texture("dots")
swipe = ultraglide.SwipePath("straight", speed_mm_s=80.0, duration_s=0.5, start_mm=(10.0, 24.0))
renderer = ultraglide.Renderer(texture, ultraglide.ExponentialModel(), ultraglide.load_profile("sim-plate"),
                               trajectory=swipe)
device = CsvPlate("envelope.csv")
device.start(ultraglide.renderer_source(device, renderer))
device.stop()
print(device.status())
