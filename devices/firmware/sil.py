"""The firmware core in this process: software in the loop.

The plate-driver firmware's portable C core (``devices/firmware/core``) and the simulator's port
(``ports/sim``) are built into a shared library when ultraglide is installed (setuptools' ext-modules,
``ultraglide.devices.firmware._sil``) and loaded here with ctypes. :class:`FirmwareCore` is one device:
bytes in and out, drive blocks out, measured blocks in. The simulated plate (``devices/sim/plate.py``)
wraps it with the plate's physics; nothing of the protocol is implemented in Python.

Time is what the caller renders: :meth:`FirmwareCore.render` produces drive samples at
``sample_rate_hz`` (48 kHz) and ticks the core every millisecond of them; :meth:`FirmwareCore.sense`
gives it the amplitude measured over the same samples. The calls are not thread-safe: serialise them.

>>> core = FirmwareCore(max_amplitude_um_pp=6.0, full_scale_um_pp=8.0)
>>> core.rules[:3]
('R-FRAMING', 'R-CRC', 'R-DEVICE-SEQ')
>>> core.status().enabled
0
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import os
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from ultraglide.devices.errors import DeviceError

HERE = Path(__file__).resolve().parent
MAX_RENDER = 48000  # drive samples one render() call returns at most (1 s at 48 kHz)
TX_CHUNK = 65536


class FirmwareBuildError(DeviceError):
    """The firmware core's shared library is missing, or was built from other sources than those beside it."""


class Config(ctypes.Structure):
    """struct ug_config (include/ug_core.h)."""

    _fields_ = [("resonance_hz", ctypes.c_float), ("q", ctypes.c_float), ("full_scale_um_pp", ctypes.c_float),
                ("max_amplitude_um_pp", ctypes.c_float), ("max_drive_um_pp", ctypes.c_float),
                ("carrier_min_hz", ctypes.c_float), ("carrier_max_hz", ctypes.c_float),
                ("carrier_hz", ctypes.c_float), ("min_setpoint_rate_hz", ctypes.c_uint32),
                ("max_setpoint_rate_hz", ctypes.c_uint32), ("watchdog_ms", ctypes.c_uint16),
                ("buffer_ms", ctypes.c_uint16), ("sample_rate_hz", ctypes.c_uint32),
                ("dac_oversample", ctypes.c_uint16), ("sensors", ctypes.c_uint8), ("sensor_rate_hz", ctypes.c_uint16),
                ("features", ctypes.c_uint8), ("max_version", ctypes.c_uint8), ("sim_faults", ctypes.c_uint8),
                ("sense_delay_samples", ctypes.c_uint16), ("link_bytes_per_s", ctypes.c_uint32),
                ("reset_stated", ctypes.c_uint8), ("reset_reason", ctypes.c_uint8), ("reset_detail", ctypes.c_uint32),
                ("name", ctypes.c_char * 65)]


class Status(ctypes.Structure):
    """struct ug_status (include/ug_core.h): what the core reports of itself."""

    _fields_ = [("enabled", ctypes.c_uint8), ("playback", ctypes.c_uint8), ("loop", ctypes.c_uint8),
                ("session_version", ctypes.c_uint8), ("faults", ctypes.c_uint16), ("buffered", ctypes.c_uint16),
                ("stream_rate_hz", ctypes.c_uint32), ("expected_index", ctypes.c_uint32),
                ("carrier_hz", ctypes.c_float), ("drive", ctypes.c_float), ("measured_um_pp", ctypes.c_float),
                ("frames_ok", ctypes.c_uint32), ("crc_errors", ctypes.c_uint32), ("framing_errors", ctypes.c_uint32),
                ("setpoints", ctypes.c_uint32), ("lost_setpoints", ctypes.c_uint32),
                ("late_setpoints", ctypes.c_uint32), ("discarded_setpoints", ctypes.c_uint32),
                ("overrun_setpoints", ctypes.c_uint32), ("fault_counts", ctypes.c_uint32 * 8),
                ("naks", ctypes.c_uint32), ("rx_overflows", ctypes.c_uint32), ("tx_dropped", ctypes.c_uint32),
                ("events_dropped", ctypes.c_uint32), ("now_ms", ctypes.c_uint32),
                ("next_telemetry_ms", ctypes.c_uint32), ("samples", ctypes.c_uint64), ("stage_hot", ctypes.c_uint8),
                ("lost_ms", ctypes.c_uint32)]

    def __repr__(self) -> str:
        return (f"Status(enabled={self.enabled}, playback={self.playback}, faults={self.faults:#06x}, "
                f"setpoints={self.setpoints}, drive={self.drive:.4f}, measured_um_pp={self.measured_um_pp:.4f})")


class Event(ctypes.Structure):
    """struct ug_event: one thing that happened, stamped with the drive sample count."""

    _fields_ = [("sample", ctypes.c_uint64), ("time_ms", ctypes.c_uint32), ("kind", ctypes.c_uint8),
                ("a", ctypes.c_uint8), ("b", ctypes.c_uint16), ("value", ctypes.c_float)]


# enum ug_event_kind
EV_HELLO, EV_CARRIER, EV_ENABLED, EV_DISABLED, EV_STREAM_STARTED, EV_STREAM_STOPPED, EV_FAULT, EV_LOOP, \
    EV_SIM_FAULT = range(1, 10)
DISABLED_WHY = {1: "host", 2: "trip", 3: "overheat", 4: "hello"}


def library_path() -> Path:
    spec = importlib.util.find_spec("ultraglide.devices.firmware._sil")
    if spec is not None and spec.origin and Path(spec.origin).is_file():
        return Path(spec.origin)
    raise FirmwareBuildError("the firmware core is not built (no ultraglide/devices/firmware/_sil*.so): install "
                             "ultraglide with its build (`./run tests --co -q` in a checkout, or `pip install .`)")


SOURCE_PATTERNS = ("core/*.c", "core/*.h", "core/*.inc", "include/*.h", "ports/sim/*.c", "ports/sim/*.h")


def sources_digest() -> str:
    """SHA-256 of the firmware sources beside this module, as setup.py computes it for the library it builds."""
    digest = hashlib.sha256()
    for pattern in SOURCE_PATTERNS:
        for path in sorted(HERE.glob(pattern)):
            digest.update(path.relative_to(HERE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _check_fresh(lib: ctypes.CDLL) -> None:
    """A library built from other sources than those beside it runs other code: refuse it."""
    built = lib.ug_sim_sources_digest().decode()
    if built != sources_digest():
        raise FirmwareBuildError("the firmware core's library was built from other sources than those beside it: "
                                 "rebuild it (`./run tests --co -q`, or `pip install -e .`)")


_LIBRARY: ctypes.CDLL | None = None
_LOAD_LOCK = threading.Lock()


def load() -> ctypes.CDLL:
    """The shared library, loaded once, its functions typed and its structures' sizes checked."""
    global _LIBRARY
    with _LOAD_LOCK:
        if _LIBRARY is not None:
            return _LIBRARY
        lib = ctypes.CDLL(os.fspath(library_path()))
        size = ctypes.c_size_t
        voidp = ctypes.c_void_p
        signatures = {
            "ug_sim_size": (size, []), "ug_sim_config_size": (size, []), "ug_sim_status_size": (size, []),
            "ug_sim_event_size": (size, []), "ug_sim_config_defaults": (None, [ctypes.POINTER(Config)]),
            "ug_sim_init": (ctypes.c_int, [voidp, ctypes.POINTER(Config)]),
            "ug_sim_set_breaks": (ctypes.c_bool, [voidp, ctypes.c_uint32]),
            "ug_sim_break_rule": (ctypes.c_char_p, [ctypes.c_uint]),
            "ug_sim_poll": (None, [voidp]), "ug_sim_receive": (size, [voidp, voidp, size, ctypes.c_uint32]),
            "ug_sim_take_tx": (size, [voidp, voidp, size]), "ug_sim_render": (None, [voidp, voidp, size]),
            "ug_sim_sense": (size, [voidp, voidp, voidp, voidp, size]),
            "ug_sim_dac": (None, [voidp, voidp, size]), "ug_sim_set_stage_hot": (None, [voidp, ctypes.c_int]),
            "ug_sim_excuse": (None, [voidp, ctypes.c_uint32]),
            "ug_sim_status": (None, [voidp, ctypes.POINTER(Status)]),
            "ug_sim_next_event": (ctypes.c_int, [voidp, ctypes.POINTER(Event)]),
            "ug_sim_take_fault": (ctypes.c_int, [voidp, ctypes.POINTER(ctypes.c_uint8),
                                                 ctypes.POINTER(ctypes.c_uint16)]),
            "ug_crc32": (ctypes.c_uint32, [voidp, size]), "ug_cobs_encode": (size, [voidp, size, voidp]),
            "ug_sim_sources_digest": (ctypes.c_char_p, []),
            "ug_sim_output_safe_calls": (ctypes.c_uint32, [voidp, ctypes.POINTER(ctypes.c_uint8)]),
            "ug_sim_lost_time": (None, [voidp, ctypes.c_uint32]),
            "ug_sim_set_samples_since_block": (None, [voidp, ctypes.c_uint32]),
        }
        for name, (result, arguments) in signatures.items():
            function = getattr(lib, name)
            function.restype = result
            function.argtypes = arguments
        _check_fresh(lib)
        for name, structure in (("config", Config), ("status", Status), ("event", Event)):
            if getattr(lib, f"ug_sim_{name}_size")() != ctypes.sizeof(structure):
                raise FirmwareBuildError(f"struct ug_{name} in the library does not match firmware/sil.py's")
        _LIBRARY = lib
        return lib


def rules() -> tuple[str, ...]:
    """The rule identifiers of docs/protocol.md the simulator can break, in the core's order."""
    lib = load()
    found = []
    while (name := lib.ug_sim_break_rule(len(found))) is not None:
        found.append(name.decode())
    return tuple(found)


@dataclass(frozen=True)
class CoreSettings:
    """What the simulated firmware is configured with (HELLO_REPLY tells the host most of it).

    Amplitudes µm peak-to-peak, frequencies Hz; ``q`` the plate's nominal quality factor (the limiter's and
    the amplitude loop's model); ``max_version`` 3, or 2 for a device that speaks only v2; ``breaks`` rule
    identifiers of docs/protocol.md to break on purpose (R-NAK-ORDER, ...)."""

    resonance_hz: float = 25000.0
    q: float = 200.0
    full_scale_um_pp: float = 8.0
    max_amplitude_um_pp: float = 6.0
    max_drive_um_pp: float | None = None
    carrier_min_hz: float = 20000.0
    carrier_max_hz: float = 28000.0
    carrier_hz: float | None = None
    min_setpoint_rate_hz: int = 1000
    max_setpoint_rate_hz: int = 48000
    watchdog_ms: int = 100
    buffer_ms: int = 250
    sample_rate_hz: int = 48000
    dac_oversample: int = 4
    sensors: int = 1  # vibration amplitude (the sensing piezo)
    sensor_rate_hz: int = 1000
    features: int = 1  # the amplitude loop
    max_version: int = 3
    sim_faults: bool = True
    sense_delay_samples: int = 0
    link_bytes_per_s: int = 0  # what its link carries, stated in HELLO_REPLY v3 (0: not stated)
    reset_stated: bool = False  # HELLO_REPLY v3 says why it last started (FEATURE_RESET_STATED) ...
    reset_reason: int = 0  # ... RESTART_* ...
    reset_detail: int = 0  # ... and the watchdog's marks seen or the fault's status
    name: str = "ultraglide plate simulator"
    breaks: tuple[str, ...] = ()

    @classmethod
    def of(cls, profile, **overrides) -> CoreSettings:
        """The settings of a device built for ``profile`` (a PlateProfile)."""
        return cls(resonance_hz=profile.resonance_hz, q=profile.q, full_scale_um_pp=profile.full_scale_um_pp,
                   max_amplitude_um_pp=profile.max_amplitude_um_pp, max_drive_um_pp=profile.max_drive_um_pp,
                   carrier_min_hz=profile.carrier_min_hz, carrier_max_hz=profile.carrier_max_hz, **overrides)

    def config(self) -> Config:
        config = Config()
        for field in Config._fields_:
            name = field[0]
            if name == "name":
                config.name = self.name.encode()[:64].decode("utf-8", "ignore").encode()
            elif name == "max_drive_um_pp":
                config.max_drive_um_pp = self.max_amplitude_um_pp if self.max_drive_um_pp is None else \
                    self.max_drive_um_pp
            elif name == "carrier_hz":
                config.carrier_hz = self.resonance_hz if self.carrier_hz is None else self.carrier_hz
            else:
                setattr(config, name, getattr(self, name))
        return config


class FirmwareCore:
    """One simulated plate driver running the firmware core (see the module docstring)."""

    def __init__(self, settings: CoreSettings | None = None, **fields):
        self.settings = settings if settings is not None else CoreSettings(**fields)
        self._lib = lib = load()
        size = lib.ug_sim_size()
        self._memory = np.zeros((size + 7) // 8, dtype=np.uint64)  # the core's state: aligned, ours to keep
        self._sim = ctypes.c_void_p(self._memory.ctypes.data)
        config = self.settings.config()
        if lib.ug_sim_init(self._sim, ctypes.byref(config)) != 0:
            raise DeviceError(f"the firmware core refused its configuration: {self.settings}")
        known = rules()
        unknown = [rule for rule in self.settings.breaks if rule not in known]
        if unknown:
            raise DeviceError(f"no rule {', '.join(unknown)} to break; the rules are {', '.join(known)}")
        mask = sum(1 << known.index(rule) for rule in set(self.settings.breaks))
        if not lib.ug_sim_set_breaks(self._sim, mask):
            raise DeviceError("this build of the firmware core cannot break rules")
        self.rules = known
        self.sample_rate_hz = self.settings.sample_rate_hz
        self._drive = np.zeros(MAX_RENDER, dtype=np.float32)
        self._drive_at = ctypes.c_void_p(self._drive.ctypes.data)
        self._sensed = np.zeros((3, MAX_RENDER), dtype=np.float32)
        self._sensed_at = [ctypes.c_void_p(self._sensed[k].ctypes.data) for k in range(3)]
        self._tx = np.zeros(TX_CHUNK, dtype=np.uint8)
        self._tx_at = ctypes.c_void_p(self._tx.ctypes.data)
        self._status = Status()
        self._event = Event()

    def __repr__(self) -> str:
        s = self.settings
        return (f"FirmwareCore({s.name!r}: {s.resonance_hz:g} Hz, Q {s.q:g}, full scale {s.full_scale_um_pp:g} µm p-p, "
                f"limit {s.max_amplitude_um_pp:g} µm p-p, v{s.max_version}"
                f"{', breaks ' + ' '.join(s.breaks) if s.breaks else ''})")

    # ---- the link ----
    def receive(self, data: bytes, lag_ms: int = 0, samples_since: int = 0) -> None:
        """Bytes from the host (any chunking); frames are handled at once. ``lag_ms``: how far the caller's real
        time is ahead of the core's clock (a valid frame feeds the watchdog at that time); ``samples_since``: the
        same in drive samples past those rendered and sensed (a CLOCK_REPLY states the sensor clock there, as a
        board reads its ADC's position: ``ug_port_samples_since_block``)."""
        if data:
            buffer = (ctypes.c_char * len(data)).from_buffer_copy(data)
            self._lib.ug_sim_set_samples_since_block(self._sim, max(0, min(int(samples_since), 0xFFFFFFFF)))
            self._lib.ug_sim_receive(self._sim, buffer, len(data), max(0, int(lag_ms)))

    def transmit(self) -> bytes:
        """Every byte the core has queued for the host."""
        out = b""
        while True:
            n = self._lib.ug_sim_take_tx(self._sim, self._tx_at, TX_CHUNK)
            out += self._tx[:n].tobytes()
            if n < TX_CHUNK:
                return out

    def poll(self) -> None:
        self._lib.ug_sim_poll(self._sim)

    # ---- time, drive and measurement ----
    def render(self, n: int) -> np.ndarray:
        """The next ``n`` drive samples (fractions of full scale, float32; a view valid until the next call)."""
        if not 0 <= n <= MAX_RENDER:
            raise ValueError(f"render 0 to {MAX_RENDER} samples at a time, not {n}")
        self._lib.ug_sim_render(self._sim, self._drive_at, n)
        return self._drive[:n]

    def sense(self, amplitude_um_pp: np.ndarray, normal_force_n: np.ndarray | None = None,
              lateral_force_n: np.ndarray | None = None) -> int:
        """The plate's measured amplitude (µm p-p) and forces (N) over the samples just rendered; returns the
        sample at which the core cut its drive (a trip), or the block's length."""
        n = len(amplitude_um_pp)
        sensed, at = self._sensed, self._sensed_at  # the three rows, written in place (a plate's every block)
        sensed[0, :n] = amplitude_um_pp
        if normal_force_n is not None:
            sensed[1, :n] = normal_force_n
        if lateral_force_n is not None:
            sensed[2, :n] = lateral_force_n
        return self._lib.ug_sim_sense(self._sim, at[0], None if normal_force_n is None else at[1],
                                      None if lateral_force_n is None else at[2], n)

    def dac(self, n_dac: int) -> np.ndarray:
        """The next ``n_dac`` carrier samples as a DAC plays them (int16, ±32767 at full-scale drive)."""
        out = np.zeros(n_dac, dtype=np.int16)
        self._lib.ug_sim_dac(self._sim, ctypes.c_void_p(out.ctypes.data), n_dac)
        return out

    def set_stage_hot(self, hot: bool) -> None:
        self._lib.ug_sim_set_stage_hot(self._sim, 1 if hot else 0)

    def excuse(self, milliseconds: int) -> None:
        """The simulator did not run for this long: not the host's silence; the telemetry due before the
        clock has caught up that long is one frame at the end (ug_sim_excuse)."""
        self._lib.ug_sim_excuse(self._sim, max(0, int(milliseconds)))

    # ---- what it says ----
    def status(self) -> Status:
        """A fresh copy of the core's status."""
        status = Status()
        self._lib.ug_sim_status(self._sim, ctypes.byref(status))
        return status

    def events(self) -> list[Event]:
        found = []
        while self._lib.ug_sim_next_event(self._sim, ctypes.byref(self._event)):
            found.append(Event.from_buffer_copy(self._event))
        return found

    def lose_time(self, milliseconds: int) -> None:
        """A board's late block interrupt: ``milliseconds`` of the core's clock pass with no block run
        (``ug_core_lost_time``); counted in the status's ``lost_ms``."""
        self._lib.ug_sim_lost_time(self._sim, max(0, int(milliseconds)))

    def output_safe_calls(self) -> tuple[int, int]:
        """How many times the core asked the port for a silent output (``ug_port_output_safe``) and the last
        call's reason (``UG_SAFE_*``: 1 the output went off, 2 the protocol watchdog's ramp ended)."""
        why = ctypes.c_uint8()
        calls = self._lib.ug_sim_output_safe_calls(self._sim, ctypes.byref(why))
        return calls, why.value

    def fault_requests(self) -> list[tuple[int, int]]:
        """Injected transport faults the host asked for (SIM_FAULT kinds 1-4), as (kind, duration_ms)."""
        kind, duration = ctypes.c_uint8(), ctypes.c_uint16()
        found = []
        while self._lib.ug_sim_take_fault(self._sim, ctypes.byref(kind), ctypes.byref(duration)):
            found.append((kind.value, duration.value))
        return found


def crc32(data: bytes) -> int:
    """The core's CRC-32 (for tests against zlib's)."""
    buffer = (ctypes.c_char * max(1, len(data))).from_buffer_copy(data or b"\0")
    return load().ug_crc32(buffer, len(data))


def cobs_encode(data: bytes) -> bytes:
    """The core's COBS encoder (for tests against the cobs package's)."""
    source = (ctypes.c_char * max(1, len(data))).from_buffer_copy(data or b"\0")
    out = (ctypes.c_char * (len(data) + len(data) // 254 + 2))()
    n = load().ug_cobs_encode(source, len(data), out)
    return out.raw[:n]
