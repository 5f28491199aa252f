"""The audio-DAC fallback: a sound card at 96/192 kHz and an amplifier drive the piezo directly.

A sounddevice OutputStream pulls the modulated carrier in the callback from the output stage
(:mod:`ultraglide.devices.output.stage`: the limiter, then the carrier) that wraps its source; the
callback only copies: no allocation beyond the stage's, no I/O, no locks. The sample rate is the first
the device accepts that can carry the carrier; underruns are counted; stopping ramps down
through the source before the stream closes.

A device with no clock of its own (ALSA's ``null`` PCM, or a ``file`` PCM over it: a dry run into a
file) takes samples as fast as the callback gives them; unpaced, the engine would render tens of times
faster than real time at real-time priority, starving the machine, and the file would hold far more
than was played. The callback holds such a device to real time: when the samples taken run ahead of
the wall clock by more than a clocked device's buffer could (plus 1 % of the time played, far beyond
any crystal's drift), it sleeps off the lead. A sound card's lead is its buffer, within that bound,
so its callback does not sleep; a wait under 0.1 s in all is not said (a burst at the start).
"""

from __future__ import annotations

import time

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.source import BlockSource, ramp_down
from ultraglide.devices.output.stage import output_stage
from ultraglide.devices.profiles import PlateProfile

CANDIDATE_RATES = (96000, 192000, 88200, 176400, 384000)
MAX_CARRIER_FRACTION = 0.4
CLOCK_SLACK_S = 0.05  # a clocked device's lead beyond twice its latency (its buffer filled at the start)
CLOCK_DRIFT = 0.01  # and beyond this fraction of the time played (a crystal drifts by 1e-4 at most)
PACED_WORTH_SAYING_S = 0.1  # less held back in all is a burst, not a device with no clock


def import_sounddevice():
    """sounddevice, or one line on how to get PortAudio."""
    try:
        import sounddevice
    except OSError as error:  # raised by sounddevice when libportaudio is missing
        raise DeviceError(f"PortAudio is not installed ({error}); on Debian or Ubuntu: "
                          "sudo apt-get install libportaudio2") from None
    return sounddevice


def supported_rates(device=None, candidates=CANDIDATE_RATES) -> list[int]:
    """The candidate rates this output accepts (mono float32)."""
    sd = import_sounddevice()
    rates = []
    for rate in candidates:
        try:
            sd.check_output_settings(device=device, samplerate=rate, channels=1, dtype="float32")
            rates.append(rate)
        except Exception:  # noqa: BLE001 - PortAudio says no in several ways
            continue
    return rates


def choose_rate(device, carrier_hz: float, requested: int | None = None) -> int:
    """A rate the device accepts and that carries the carrier (below 0.4 of it), or a clear error."""
    needed = carrier_hz / MAX_CARRIER_FRACTION
    if requested and requested < needed:
        raise DeviceError(f"{requested} Hz cannot carry a {carrier_hz:g} Hz carrier: it needs {needed:,.0f} Hz "
                          "or more; use 96000 or 192000")
    accepted = supported_rates(device, [requested] if requested else CANDIDATE_RATES)
    wanted = [requested] if requested else CANDIDATE_RATES
    for rate in wanted:
        if rate in accepted and rate >= needed:
            return rate
    if requested and requested not in accepted:
        raise DeviceError(f"audio device {device or 'default'} does not accept {requested} Hz; it accepts "
                          f"{', '.join(map(str, accepted)) or 'none of 88.2-384 kHz'}")
    raise DeviceError(f"audio device {device or 'default'} cannot carry a {carrier_hz:g} Hz carrier: it needs "
                      f"{needed:,.0f} Hz or more and accepts {', '.join(map(str, accepted)) or 'no such rate'}; "
                      "use a 96 or 192 kHz interface")


def check_output_device(device) -> None:
    """DeviceError unless ``device`` (an index, a name or part of one; None: the default) is an audio output
    PortAudio knows; the message lists the outputs there are."""
    sd = import_sounddevice()
    try:
        info = sd.query_devices(device, kind="output") if device is not None else sd.query_devices(kind="output")
    except (ValueError, sd.PortAudioError):
        info = None
    if info is None or info.get("max_output_channels", 0) < 1:
        try:
            outputs = [f"{index} ({found['name']})" for index, found in enumerate(sd.query_devices())
                       if found["max_output_channels"] > 0]
        except sd.PortAudioError:
            outputs = []
        which = "no default audio output" if device is None else f"no such audio output: {device}"
        listed = f"outputs: {', '.join(outputs[:8])}" if outputs else "this machine has no audio output"
        raise DeviceError(f"{which}; {listed} (`ultraglide devices` lists them)")


def unclocked_lead_s(frames_taken: int, rate_hz: float, elapsed_s: float, latency_s: float) -> float:
    """How far a device's intake has run ahead of the wall clock beyond what a clocked device could, s (≤ 0: none).

    A sound card takes ``rate_hz`` samples a second by its own crystal: at most its buffer (about its latency; twice
    it, and 50 ms, allowed) ahead of the first callback's time, plus its crystal's drift (1 % allowed, a hundred times
    a poor crystal's). A device that is further ahead has no clock.

    Parameters
    ----------
    frames_taken : int
        Samples the device has taken since the first callback.
    rate_hz : float
        The stream's sample rate, Hz.
    elapsed_s : float
        Wall-clock time since the first callback, s.
    latency_s : float
        The stream's output latency, s.

    Returns
    -------
    float
        The lead to sleep off, s; 0 or less for a device that keeps time.

    Examples
    --------
    A sound card with a 20 ms buffer, an hour in, its crystal 100 ppm fast, is well within:

    >>> unclocked_lead_s(round(96000 * 3600 * 1.0001) + 1920, 96000, 3600.0, 0.02) < 0
    True

    ALSA's null PCM, which took 2 s of samples in 0.1 s:

    >>> round(unclocked_lead_s(2 * 96000, 96000, 0.1, 0.02), 3)
    1.809
    """
    lead_s = frames_taken / rate_hz - elapsed_s
    return lead_s - (2 * latency_s + CLOCK_SLACK_S + CLOCK_DRIFT * elapsed_s)


def pacing_words(device_status: dict) -> str | None:
    """One line on a device with no clock held to real time (from :meth:`AudioPlate.status`), or None.

    Parameters
    ----------
    device_status : dict
        A device's status; only an audio output's carries ``paced_s``.

    Returns
    -------
    str or None

    Examples
    --------
    >>> print(pacing_words({"device": "audio:default", "paced_s": 1.93}))  # doctest: +NORMALIZE_WHITESPACE
    audio:default took samples faster than real time (it has no clock of its own: a null or file sink, not a sound
    card); ultraglide held it to real time (1.9 s of waiting)
    >>> pacing_words({"device": "audio:0", "paced_s": 0.02}) is None  # a burst at the start
    True
    """
    paced_s = device_status.get("paced_s") or 0.0
    if paced_s < PACED_WORTH_SAYING_S:
        return None
    return (f"{device_status.get('device', 'the audio device')} took samples faster than real time (it has no clock "
            f"of its own: a null or file sink, not a sound card); ultraglide held it to real time "
            f"({paced_s:.1f} s of waiting)")


class AudioPlate:
    """A plate on a sound-card output."""

    signal = "audio"

    def __init__(self, device, profile: PlateProfile, carrier_hz: float | None = None, rate_hz: int | None = None,
                 latency: float | str = "low", blocksize: int = 0):
        self.sd = import_sounddevice()
        self.device = device
        self.profile = profile
        carrier_hz = carrier_hz or profile.resonance_hz
        profile.check_carrier(carrier_hz)
        self.carrier_hz = carrier_hz
        check_output_device(device)
        self.rate_hz = choose_rate(device, carrier_hz, rate_hz)
        self.latency = latency
        self.blocksize = blocksize
        self.underruns = 0
        self.callbacks = 0
        self.errors: list[str] = []
        self._stream = None
        self._source: BlockSource | None = None
        self._output_latency = 0.0
        self.paced_s = 0.0  # the time the callback held back a device with no clock (see the module's words)
        self._frames_taken = 0
        self._first_callback_s: float | None = None

    def _callback(self, outdata, frames, time_info, status) -> None:
        if status.output_underflow:
            self.underruns += 1
        self.callbacks += 1
        now = time.perf_counter()
        if self._first_callback_s is None:
            self._first_callback_s = now
        try:
            outdata[:, 0] = self._source.pull(frames, now + self._output_latency)
        except Exception as error:  # never let a failing source leave the plate driven
            outdata.fill(0)
            self.errors.append(f"{type(error).__name__}: {error}")
            raise self.sd.CallbackAbort from None
        self._frames_taken += frames
        excess_s = unclocked_lead_s(self._frames_taken, self.rate_hz, time.perf_counter() - self._first_callback_s,
                                    self._output_latency)
        if excess_s > 0:  # a device with no clock: only a sleep here holds it to real time
            self.paced_s += excess_s
            time.sleep(excess_s)

    def start(self, source: BlockSource) -> None:
        """Play ``source``'s drive envelope (µm p-p) through the limiter and the carrier."""
        self._source = output_stage(source, self.profile, self.signal, self.rate_hz, self.carrier_hz)
        self._frames_taken, self._first_callback_s = 0, None  # each stream's intake is paced from its own start
        try:
            self._stream = self.sd.OutputStream(samplerate=self.rate_hz, channels=1, dtype="float32",
                                                device=self.device, latency=self.latency,
                                                blocksize=self.blocksize, callback=self._callback)
            self._output_latency = float(self._stream.latency)
            self._stream.start()
        except self.sd.PortAudioError as error:
            raise DeviceError(f"cannot open audio output {self.device or 'default'}: {error}") from None

    def stop(self) -> None:
        """Ramp down through the source, then stop and close the stream."""
        if self._stream is None:
            return
        if self._source is not None and self._stream.active:
            ramp_down(self._source, lambda: self._stream.active)
            time.sleep(max(self._output_latency, 0.01))  # let the last blocks reach the DAC
        self._stream.stop()
        self._stream.close()
        self._stream = None

    def status(self) -> dict:
        return {"device": f"audio:{self.device if self.device is not None else 'default'}", "rate_hz": self.rate_hz,
                "latency_s": self._output_latency, "blocksize": self.blocksize, "underruns": self.underruns,
                "callbacks": self.callbacks, "errors": self.errors[:5], "paced_s": round(self.paced_s, 3)}
