"""The words of the demo's status line: the device and its state, faults, model, force, what the limit did,
the engine's figures, the recording, ``--watch``'s errors and where to find help."""

from __future__ import annotations


def status_words(app) -> str:
    """The status line: device and its state, model, force, percent limited in the last second, faults,
    then the engine's own figures."""
    driver = app.driver
    if app.link is None:
        words = "starting the engine (its own process; compiling its kernels)…"
        if driver.unfelt:
            words += f"   ·   {driver.unfelt} touches before it was ready: not felt"
        return words
    s = app.link.status(0.0)
    device = {"sim": "simulated plate"}.get(s.device, s.device.replace("serial:", "plate on serial ")
                                            .replace("audio:", "audio output ").replace("wav:", "recording "))
    source = "touch pressure" if driver.pressure_seen else "Up/Down keys"
    faults = "faults: " + ", ".join(s.faults) if s.faults else "no faults"
    # the engine is paused between touches (the plate rests); the user's pause is the Space key's
    state = "paused" if app.user_paused else ("running" if s.state == "paused" else s.state)
    words = (f"{device} {state}, {faults}   ·   {app.link.model_name} model   ·   "
             f"{app.force_n:.2f} N ({source})   ·   limited {s.limited_pct:.0f} % of the last second, "
             f"{s.limited_samples} samples on this texture   ·   {s.underruns} underruns, "
             f"{s.late_blocks} late blocks, block {s.block_p50_us:.0f}/{s.block_p99_us:.0f} µs p50/p99")
    if app.recorder is not None:
        words += f"   ·   recording: {app.recorder.rows} touches"
    if app.watch_errors:
        words += "   ·   " + "; ".join(app.watch_errors)
    return words + "   ·   H: help"
