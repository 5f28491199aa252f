"""Rig files: the parts a lab has, from a TOML file, typed and checked at the edge.

A rig names the plate (a profile by name or file, or the profile's fields inline), the drive chain that
turns a sample into volts and volts into motion, the output device, the touch panel over the plate and the
display under it::

    [plate]
    profile = "plate-26k.toml"          # or resonance_hz, q, max_amplitude_um_pp ... inline
    [drive]
    interface_full_scale_v = 2.0        # volts peak out of the interface for a sample of 1.0
    amplifier_gain_v_per_v = 20.0
    plate_um_pp_per_v = 0.25            # µm p-p of the plate per volt peak across it, at resonance
    [output]
    device = "audio:USB Audio?rate=192000"
    [touch]
    area_mm = [0.0, 0.0, 220.0, 140.0]  # the panel's active area: left, top, width, height, mm
    rotation_deg = 0
    pressure_full_scale_n = 4.0
    drives = "first"
    x_range = [0, 4095]                 # the panel's axis ranges, its own units (only where ultraglide reads
    y_range = [0, 4095]                 # the panel itself from a node that cannot say them: a FIFO)
    [display]
    width_mm = 220.0

**The drive chain's arithmetic.** A sample of 1.0 leaves the interface as ``interface_full_scale_v`` volts
peak; the amplifier multiplies by ``amplifier_gain_v_per_v``; at resonance the plate moves
``plate_um_pp_per_v`` µm peak-to-peak per volt peak across it. So a full-scale sample moves the plate
``full_scale_um_pp = interface_full_scale_v × amplifier_gain_v_per_v × plate_um_pp_per_v``
(2 V × 20 V/V × 0.25 µm/V = 10 µm p-p). ``amplifier_um_pp_per_v`` (µm p-p per volt peak into the amplifier)
replaces the last two factors. Where the rig names a profile that says a full scale too (a measured one), the
larger of the two is used: a sample of the limit then asks the least of the plate.

**The smallest limit wins.** The plate's ``max_amplitude_um_pp``, ``[drive] amplifier_max_v`` (the
amplifier's rated output, volts peak: × ``plate_um_pp_per_v``) and ``[drive] max_amplitude_um_pp`` (a lab's
own cap) are compared, and the smallest is the limit the resolved profile carries (never above full scale);
:attr:`Rig.limit_from` says whose it is.

Every value is checked when a rig is loaded: a wrong one is one line (a :class:`RigError`) naming the file,
the key, the value and what is allowed.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from ultraglide.devices.errors import DeviceError
from ultraglide.devices.profiles import PlateProfile, load_profile

from ultraglide.inputs import parse_toml, read_input, some_of

RIG_PREFIX = "rig:"  # a plate spec naming a rig file's plate: rig:PATH (see load_plate)
ROTATIONS_DEG = (0, 90, 180, 270)
DRIVES = ("first", "latest", "none")
VOLTS_RANGE = (0.001, 1000.0)  # an interface's full scale, an amplifier's rated output: volts peak
GAIN_RANGE = (0.001, 10000.0)  # V/V
UM_PER_V_RANGE = (1e-6, 100.0)  # µm p-p per volt peak
AREA_RANGE_MM = (0.0, 10000.0)  # a panel's corner and size, mm
AXIS_VALUE_RANGE = (-(2**31), 2**31 - 1)  # a panel's axis values (evdev's s32)
PRESSURE_RANGE_N = (0.01, 100.0)
DISPLAY_RANGE_MM = (10.0, 10000.0)
PROFILE_KEYS = {f.name for f in fields(PlateProfile)}
SECTIONS = {
    "plate": PROFILE_KEYS | {"profile"},
    "drive": {"interface_full_scale_v", "amplifier_gain_v_per_v", "plate_um_pp_per_v", "amplifier_um_pp_per_v",
              "amplifier_max_v", "max_amplitude_um_pp"},
    "output": {"device"},
    "touch": {"area_mm", "rotation_deg", "flip_x", "flip_y", "pressure_full_scale_n", "drives", "x_range", "y_range",
              "pressure_range"},
    "display": {"width_mm"},
}
TOP_KEYS = {"name", "description"}


class RigError(DeviceError):
    """A rig file that cannot be used; the message is one line naming the file and what to change."""


@dataclass(frozen=True)
class DriveChain:
    """Interface, amplifier and plate: how a sample of 1.0 becomes µm p-p of motion (see the module docstring).

    ``interface_full_scale_v``: volts peak out of the interface at a sample of 1.0;
    ``amplifier_gain_v_per_v``; ``plate_um_pp_per_v``: µm p-p per volt peak across the plate, at resonance;
    ``amplifier_um_pp_per_v``: µm p-p per volt peak into the amplifier (instead of the two before);
    ``amplifier_max_v``: the amplifier's rated output, volts peak; ``max_amplitude_um_pp``: a cap of the lab's.
    """

    interface_full_scale_v: float
    amplifier_gain_v_per_v: float | None = None
    plate_um_pp_per_v: float | None = None
    amplifier_um_pp_per_v: float | None = None
    amplifier_max_v: float | None = None
    max_amplitude_um_pp: float | None = None

    @property
    def um_pp_per_input_v(self) -> float:
        """µm p-p at the plate per volt peak into the amplifier."""
        if self.amplifier_um_pp_per_v is not None:
            return self.amplifier_um_pp_per_v
        return self.amplifier_gain_v_per_v * self.plate_um_pp_per_v

    @property
    def full_scale_um_pp(self) -> float:
        """The plate's amplitude at a sample of 1.0, µm p-p: full-scale volts × the chain's µm p-p per volt.

        Examples
        --------
        >>> DriveChain(2.0, 20.0, 0.25).full_scale_um_pp
        10.0
        """
        return self.interface_full_scale_v * self.um_pp_per_input_v

    @property
    def amplifier_limit_um_pp(self) -> float | None:
        """The amplitude at the amplifier's rated output (µm p-p), when both it and the plate's µm/V are known."""
        if self.amplifier_max_v is None:
            return None
        if self.plate_um_pp_per_v is not None:
            return self.amplifier_max_v * self.plate_um_pp_per_v
        return None

    def words(self) -> str:
        """The arithmetic in one line, e.g. ``2 V full scale × 20 V/V × 0.25 µm p-p/V = 10 µm p-p``."""
        if self.amplifier_um_pp_per_v is not None:
            chain = f"{self.interface_full_scale_v:g} V full scale × {self.amplifier_um_pp_per_v:g} µm p-p/V"
        else:
            chain = (f"{self.interface_full_scale_v:g} V full scale × {self.amplifier_gain_v_per_v:g} V/V × "
                     f"{self.plate_um_pp_per_v:g} µm p-p/V")
        return f"{chain} = {self.full_scale_um_pp:g} µm p-p at a sample of 1.0 (full_scale_um_pp)"


@dataclass(frozen=True)
class TouchPanel:
    """The touch panel over the plate: where its active area lies, how it is turned, its pressure scale and
    which touch drives the plate when two are down.

    ``area_mm``: (left, top, width, height) of the active area, mm from the display's top-left corner as the
    display shows it (x right, y down). A touch's normalised panel coordinates (0..1 each way, as SDL gives
    them) are turned by ``rotation_deg`` (clockwise, as the panel is mounted), then flipped, then scaled onto
    the area (:meth:`to_mm`). ``pressure_full_scale_n``: the force at the panel's pressure 1.0 (None: the
    panel measures no pressure; the demo's own force applies). ``drives``: ``first`` (the first touch down
    drives until it lifts), ``latest`` (the newest touch down takes over) or ``none`` (with two down, none
    drives: the plate rests until one lifts).
    ``x_range``, ``y_range``, ``pressure_range``: the panel's axis ranges (min, max) in its own units, for
    ``serve --touch-panel`` reading a node that cannot say them itself (a FIFO of evdev records; a real evdev
    device says them and these override it); None when not given.
    """

    area_mm: tuple[float, float, float, float] | None = None
    rotation_deg: int = 0
    flip_x: bool = False
    flip_y: bool = False
    pressure_full_scale_n: float | None = None
    drives: str = "first"
    x_range: tuple[int, int] | None = None
    y_range: tuple[int, int] | None = None
    pressure_range: tuple[int, int] | None = None

    @property
    def axis_ranges(self) -> dict:
        """The axis ranges given, ``{"x": (min, max), ...}`` (panel units): those the rig gives."""
        return {axis: span for axis, span in (("x", self.x_range), ("y", self.y_range),
                                              ("pressure", self.pressure_range)) if span is not None}

    def to_mm(self, u: float, v: float, full_area_mm: tuple[float, float] | None = None) -> tuple[float, float]:
        """A touch at normalised panel coordinates ``(u, v)`` (0..1, x right, y down as the panel reports
        them) as mm on the display.

        The panel's axes are turned back by ``rotation_deg`` (a panel mounted turned 90° clockwise reports its
        x along the display's y), then flipped, then placed on ``area_mm``; without an area, on
        ``full_area_mm`` (width, height: the whole display).

        Examples
        --------
        >>> TouchPanel((10.0, 20.0, 200.0, 100.0), rotation_deg=90).to_mm(0.25, 0.0)
        (210.0, 45.0)
        """
        if self.rotation_deg == 90:
            u, v = 1.0 - v, u
        elif self.rotation_deg == 180:
            u, v = 1.0 - u, 1.0 - v
        elif self.rotation_deg == 270:
            u, v = v, 1.0 - u
        if self.flip_x:
            u = 1.0 - u
        if self.flip_y:
            v = 1.0 - v
        if self.area_mm is not None:
            left, top, width, height = self.area_mm
        elif full_area_mm is not None:
            (width, height), left, top = full_area_mm, 0.0, 0.0
        else:
            raise ValueError("a panel without an area_mm needs the display's size (full_area_mm)")
        return left + u * width, top + v * height

    def force_n(self, pressure: float) -> float | None:
        """The force (N) for a panel's pressure reading (0..1), or None when the panel has no pressure scale."""
        if self.pressure_full_scale_n is None:
            return None
        return max(0.0, min(pressure, 1.0)) * self.pressure_full_scale_n


@dataclass(frozen=True)
class Rig:
    """A lab's rig as its file says, resolved: :attr:`plate` is the profile to drive with (the chain's full
    scale, the smallest limit). Load with :func:`load_rig`."""

    path: str
    name: str
    plate: PlateProfile
    plate_source: str  # the profile's name or file, or "inline"
    drive: DriveChain | None
    device: str | None
    touch: TouchPanel | None
    display_width_mm: float | None
    limit_from: str  # whose limit binds: "the plate", "the amplifier's rated output", "[drive] max_amplitude_um_pp"
    limits_um_pp: dict = field(default_factory=dict)  # every limit declared, µm p-p, by who declared it
    description: str = ""
    profile_full_scale_um_pp: float | None = None  # what a named profile said before the chain replaced it

    @property
    def full_scale_um_pp(self) -> float:
        return self.plate.full_scale_um_pp

    @property
    def max_amplitude_um_pp(self) -> float:
        return self.plate.max_amplitude_um_pp

    def unverified(self) -> list[str]:
        """What loading the file could not check, one sentence each: what a lab must measure or look at."""
        said = []
        if self.drive is not None:
            said.append("the drive chain's figures are taken as written: measure the plate's amplitude at a known "
                        "drive (plate sweep --sensor) before trusting full_scale_um_pp")
            named, chain = self.profile_full_scale_um_pp, self.drive.full_scale_um_pp
            if named is not None and abs(named - chain) > 0.02 * max(named, chain):
                per_v = named / (self.drive.interface_full_scale_v * (self.drive.amplifier_gain_v_per_v or 1.0))
                which = "plate_um_pp_per_v" if self.drive.amplifier_gain_v_per_v else "amplifier_um_pp_per_v"
                said.append(f"profile {self.plate_source} says full_scale_um_pp = {named:g} and the drive chain "
                            f"{chain:g}: the larger is used (a sample of the limit then asks less of the plate); if "
                            f"the profile was measured, set {which} = {per_v:.4g} so that they agree")
        else:
            said.append("full_scale_um_pp is the profile's, not derived from a drive chain ([drive] absent)")
        said.append("the plate's resonance and Q are taken as written: plate sweep measures them")
        if self.device is None:
            said.append("no [output] device: commands use --device, or the simulated plate")
        elif self.device.split(":", 1)[0].split("?", 1)[0] in ("audio", "serial"):
            said.append(f"the output device {self.device} was not opened: ultraglide devices lists what is connected")
        if self.touch is not None:
            said.append("the touch panel's mapping is taken as written: touch the display's corners in the demo "
                        "and see the trace land under the finger")
        if self.display_width_mm is not None:
            said.append("the display's width is taken as written: a 100 mm texture should measure 100 mm on it")
        return said

    def as_dict(self) -> dict:
        """Plain values for ``rig check --json``."""
        plate = {f.name: getattr(self.plate, f.name) for f in fields(PlateProfile)}
        return {
            "rig": self.path, "name": self.name, "plate_source": self.plate_source, "plate": plate,
            "full_scale_um_pp": self.full_scale_um_pp, "max_amplitude_um_pp": self.max_amplitude_um_pp,
            "max_drive_um_pp": self.plate.max_drive_um_pp, "limit_from": self.limit_from,
            "limits_um_pp": dict(self.limits_um_pp),
            "drive": None if self.drive is None else {
                **{f.name: getattr(self.drive, f.name) for f in fields(DriveChain)},
                "um_pp_per_input_v": self.drive.um_pp_per_input_v},
            "device": self.device,
            "touch": None if self.touch is None else {
                "area_mm": None if self.touch.area_mm is None else list(self.touch.area_mm),
                "rotation_deg": self.touch.rotation_deg, "flip_x": self.touch.flip_x, "flip_y": self.touch.flip_y,
                "pressure_full_scale_n": self.touch.pressure_full_scale_n, "drives": self.touch.drives,
                **{f"{axis}_range": list(span) for axis, span in self.touch.axis_ranges.items()}},
            "display": None if self.display_width_mm is None else {"width_mm": self.display_width_mm},
            "unverified": self.unverified(),
        }


class _Reader:
    """Typed reads of one table of a rig file, each failure one line naming the file and the key."""

    def __init__(self, path, section: str, table: dict):
        self.path, self.section, self.table = path, section, table

    def fail(self, key: str, message: str) -> RigError:
        return RigError(f"{self.path}: [{self.section}] {key} {message}")

    def number(self, key: str, low: float, high: float, unit: str, required: bool = False) -> float | None:
        if key not in self.table:
            if required:
                raise self.fail(key, f"is missing: give it in {unit}")
            return None
        value = self.table[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, f"must be a number of {unit}, got {_shown(value)}")
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number) or not low <= number <= high:
            raise self.fail(key, f"= {_shown(value)} is outside {low:g}..{high:g} {unit}")
        return number

    def flag(self, key: str) -> bool:
        value = self.table.get(key, False)
        if not isinstance(value, bool):
            raise self.fail(key, f"must be true or false, got {_shown(value)}")
        return value

    def text(self, key: str) -> str | None:
        if key not in self.table:
            return None
        value = self.table[key]
        if not isinstance(value, str) or not value or not value.isprintable() or len(value) > 1000:
            raise self.fail(key, f"must be a line of text, got {_shown(value)}")
        return value


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def load_rig(path: str | os.PathLike) -> Rig:
    """A rig from its TOML file, resolved: the plate's profile with the drive chain's full scale and the
    smallest limit anyone declares.

    Parameters
    ----------
    path : str or path-like
        The rig file (a regular file; a profile it names by a relative path is read beside it).

    Returns
    -------
    Rig
        ``rig.plate`` is the :class:`PlateProfile` to drive with; amplitudes in µm p-p.

    Raises
    ------
    RigError
        One line naming the file, the key and what is allowed, for anything wrong in it.

    Examples
    --------
    >>> rig = load_rig("examples/rig.toml")       # doctest: +SKIP  (a file of the repository's)
    >>> rig.full_scale_um_pp, rig.max_amplitude_um_pp  # doctest: +SKIP
    (10.0, 5.0)
    """
    path = Path(os.fspath(path))
    data = parse_toml(read_input(path, "rig file", RigError), f"{path}", RigError, what="rig file")
    unknown = sorted(set(data) - set(SECTIONS) - TOP_KEYS)
    if unknown:
        raise RigError(f"{path}: unknown tables or keys {some_of(unknown)}; a rig has [plate], [drive], [output], "
                       f"[touch], [display] (and name, description)")
    tables = {}
    for section, known in SECTIONS.items():
        table = data.get(section, {})
        if not isinstance(table, dict):
            raise RigError(f"{path}: {section} must be a table ([{section}]), got {_shown(table)}")
        extra = sorted(set(table) - known)
        if extra:
            raise RigError(f"{path}: unknown keys in [{section}]: {some_of(extra)}; known: {', '.join(sorted(known))}")
        tables[section] = table
    top = _Reader(path, "top", data)
    name = top.text("name") or path.stem
    description = top.text("description") or ""
    if "plate" not in data:
        raise RigError(f"{path}: no [plate]: name its profile (profile = \"NAME\" or a file) or give its fields "
                       "(resonance_hz, q, max_amplitude_um_pp ...)")
    drive = _drive(_Reader(path, "drive", tables["drive"])) if "drive" in data else None
    plate, source, declared = _plate(path, tables["plate"], drive, name)
    plate, limit_from, limits = _limits(path, plate, declared, drive)
    device = _device(_Reader(path, "output", tables["output"]))
    _check_rate(path, plate, device)
    touch = _touch(_Reader(path, "touch", tables["touch"])) if "touch" in data else None
    display = _Reader(path, "display", tables["display"]).number("width_mm", *DISPLAY_RANGE_MM, "mm",
                                                                 required="display" in data)
    named = None
    if source != "inline" and drive is not None:
        named = load_profile(source).full_scale_um_pp
    return Rig(str(path), name, plate, source, drive, device, touch, display, limit_from, limits, description, named)


def _drive(read: _Reader) -> DriveChain:
    volts = read.number("interface_full_scale_v", *VOLTS_RANGE, "V peak", required=True)
    gain = read.number("amplifier_gain_v_per_v", *GAIN_RANGE, "V/V")
    plate = read.number("plate_um_pp_per_v", *UM_PER_V_RANGE, "µm p-p per V peak")
    direct = read.number("amplifier_um_pp_per_v", *UM_PER_V_RANGE[:1], 1e6, "µm p-p per V peak")
    if direct is not None and gain is not None:
        raise read.fail("amplifier_um_pp_per_v", "replaces amplifier_gain_v_per_v × plate_um_pp_per_v: give one "
                        "way or the other")
    if direct is None and (gain is None or plate is None):
        raise read.fail("amplifier_gain_v_per_v", "and plate_um_pp_per_v (or amplifier_um_pp_per_v alone) are "
                        "needed: how volts into the amplifier become µm p-p")
    return DriveChain(volts, gain, plate, direct, read.number("amplifier_max_v", *VOLTS_RANGE, "V peak"),
                      read.number("max_amplitude_um_pp", 0.0001, 1000.0, "µm p-p"))


def _plate(path: Path, table: dict, drive: DriveChain | None, rig_name: str) -> tuple[PlateProfile, str, float]:
    """The plate's profile (at the chain's full scale, its limit no higher), where it came from, and the limit
    the plate itself declares (µm p-p)."""
    read = _Reader(path, "plate", table)
    spec = read.text("profile")
    inline = {key: value for key, value in table.items() if key != "profile"}
    if spec is not None:
        if inline:
            raise RigError(f"{path}: [plate] names profile {spec!r} and gives {some_of(sorted(inline))} too: "
                           "name a profile or give its fields, not both")
        named = Path(spec)
        if not named.is_absolute() and ("/" in spec or spec.endswith(".toml")):
            spec = str(path.parent / named)  # a file beside the rig
        try:
            profile = load_profile(spec)
        except DeviceError as error:
            raise RigError(f"{path}: [plate] profile: {error}") from None
        declared = profile.max_amplitude_um_pp
        if drive is not None:  # two say it: the larger, on which a sample of the limit asks less of the plate
            profile = _rescaled(path, profile, max(drive.full_scale_um_pp, profile.full_scale_um_pp))
        return profile, spec, declared
    if "full_scale_um_pp" in inline and drive is not None:
        raise RigError(f"{path}: [plate] full_scale_um_pp = {_shown(inline['full_scale_um_pp'])} and a [drive] "
                       f"chain ({drive.full_scale_um_pp:g} µm p-p) both say it: leave it to [drive]")
    if "full_scale_um_pp" not in inline and drive is None:
        raise RigError(f"{path}: nothing says the plate's full scale: give [drive] (interface volts, amplifier, "
                       "plate µm/V) or [plate] full_scale_um_pp")
    missing = [key for key in ("resonance_hz", "q", "max_amplitude_um_pp") if key not in inline]
    if missing:
        raise RigError(f"{path}: [plate] lacks {', '.join(missing)} (or name a profile: profile = \"NAME\")")
    inline.setdefault("name", f"{rig_name}'s plate")
    declared = inline["max_amplitude_um_pp"]
    if drive is not None:
        inline["full_scale_um_pp"] = drive.full_scale_um_pp
        if isinstance(declared, int | float) and not isinstance(declared, bool) and declared > drive.full_scale_um_pp:
            inline["max_amplitude_um_pp"] = drive.full_scale_um_pp  # the chain cannot reach more: _limits says so
            inline.pop("max_drive_um_pp", None)
    try:
        profile = PlateProfile(**inline)
    except DeviceError as error:
        raise RigError(f"{path}: [plate] {error}") from None
    return profile, "inline", float(declared)


def _rescaled(path: Path, profile: PlateProfile, full_scale_um_pp: float) -> PlateProfile:
    """The profile at the chain's full scale; a limit or drive ceiling above it comes down to it."""
    limit = min(profile.max_amplitude_um_pp, full_scale_um_pp)
    drive = min(profile.max_drive_um_pp, full_scale_um_pp)
    try:
        rescaled = replace(profile, full_scale_um_pp=full_scale_um_pp, max_amplitude_um_pp=limit,
                           max_drive_um_pp=max(limit, drive))
    except DeviceError as error:
        raise RigError(f"{path}: [drive] gives full_scale_um_pp = {full_scale_um_pp:g}, which profile "
                       f"{profile.shown_name} cannot take: {error}") from None
    return rescaled


def _limits(path: Path, plate: PlateProfile, declared: float, drive: DriveChain | None
            ) -> tuple[PlateProfile, str, dict]:
    """The plate with the smallest limit anyone declares, whose it is, and every one declared (µm p-p)."""
    limits = {"the plate": declared, "full scale": plate.full_scale_um_pp}
    if drive is not None:
        if drive.amplifier_limit_um_pp is not None:
            limits["the amplifier's rated output"] = drive.amplifier_limit_um_pp
        if drive.max_amplitude_um_pp is not None:
            limits["[drive] max_amplitude_um_pp"] = drive.max_amplitude_um_pp
    whose = min(limits, key=lambda who: (limits[who], who != "the plate"))
    limit = limits[whose]
    if limit < plate.max_amplitude_um_pp:
        try:
            plate = replace(plate, max_amplitude_um_pp=limit, max_drive_um_pp=max(limit, min(plate.max_drive_um_pp,
                                                                                           limit)))
        except DeviceError as error:
            raise RigError(f"{path}: the smallest limit, {limit:g} µm p-p ({whose}), is unusable: {error}") from None
    return plate, whose, limits


def _device(read: _Reader) -> str | None:
    device = read.text("device")
    if device is None:
        return None
    from ultraglide.devices.urls import parse_device_url

    try:
        parse_device_url(device)
    except DeviceError as error:
        raise read.fail("device", f"is not a device: {error}") from None
    return device


def _check_rate(path: Path, plate: PlateProfile, device: str | None) -> None:
    """An audio device's rate, when the rig gives one, must carry the plate's carrier at resonance."""
    if device is None:
        return
    from ultraglide.devices.urls import parse_device_url

    url = parse_device_url(device)
    rate = url.options.get("rate")
    if url.kind in ("audio", "wav", "null") and rate is not None:
        try:
            plate.check_carrier(plate.resonance_hz, rate)
        except DeviceError as error:
            raise RigError(f"{path}: [output] device {device}: {error}") from None


def _touch(read: _Reader) -> TouchPanel:
    area = None
    if "area_mm" in read.table:
        value = read.table["area_mm"]
        if not isinstance(value, list) or len(value) != 4:
            raise read.fail("area_mm", f"must be [left, top, width, height] in mm, got {_shown(value)}")
        corner = _Reader(read.path, "touch", {"area_mm": 0})
        numbers = []
        for number in value:
            corner.table = {"area_mm": number}
            numbers.append(corner.number("area_mm", *AREA_RANGE_MM, "mm (each of left, top, width, height)"))
        if numbers[2] <= 0 or numbers[3] <= 0:
            raise read.fail("area_mm", f"has a width and height of {numbers[2]:g} × {numbers[3]:g} mm: both must "
                            "be more than 0")
        area = tuple(numbers)
    rotation = read.table.get("rotation_deg", 0)
    if isinstance(rotation, bool) or rotation not in ROTATIONS_DEG:
        raise read.fail("rotation_deg", f"must be 0, 90, 180 or 270, got {_shown(rotation)}")
    drives = read.table.get("drives", "first")
    if drives not in DRIVES:
        raise read.fail("drives", f"must be \"first\", \"latest\" or \"none\", got {_shown(drives)}")
    ranges = {key: _axis_range(read, key) for key in ("x_range", "y_range", "pressure_range")}
    if (ranges["x_range"] is None) != (ranges["y_range"] is None):
        given = "x_range" if ranges["x_range"] is not None else "y_range"
        raise read.fail(given, "is given without the other: give both x_range and y_range")
    return TouchPanel(area, int(rotation), read.flag("flip_x"), read.flag("flip_y"),
                      read.number("pressure_full_scale_n", *PRESSURE_RANGE_N, "N"), drives, **ranges)


def _axis_range(read: _Reader, key: str) -> tuple[int, int] | None:
    """``[min, max]``: whole numbers of the panel's units (evtest's Min and Max), min < max."""
    if key not in read.table:
        return None
    value = read.table[key]
    low, high = AXIS_VALUE_RANGE
    if not isinstance(value, list) or len(value) != 2 or not all(
            isinstance(v, int) and not isinstance(v, bool) and low <= v <= high for v in value) \
            or value[0] >= value[1]:
        raise read.fail(key, f"must be [min, max], whole numbers of the panel's units with min < max (evtest prints "
                        f"them), got {_shown(value)}")
    return value[0], value[1]


def load_plate(spec: str) -> PlateProfile:
    """The plate a spec names: ``rig:PATH`` is that rig's resolved plate, anything else a profile
    (:func:`~ultraglide.devices.profiles.load_profile`: a bundled name or a TOML file).

    Parameters
    ----------
    spec : str
        ``rig:PATH``, ``hello:{...}`` (the plate a device's handshake described), a bundled profile's name or a
        profile file.

    Returns
    -------
    PlateProfile
        Amplitudes in µm p-p, frequencies in Hz.

    Raises
    ------
    DeviceError
        One line, for a bad rig or profile.

    Examples
    --------
    >>> load_plate("sim-plate").max_amplitude_um_pp
    6.0
    """
    spec = os.fspath(spec)
    if spec.startswith(RIG_PREFIX):
        return load_rig(spec[len(RIG_PREFIX):]).plate
    from ultraglide.devices.serial.handshake import HELLO_PREFIX, plate_of_spec

    if spec.startswith(HELLO_PREFIX):  # the plate a device's handshake described (apps/commands/plate_choice.py)
        return plate_of_spec(spec)
    return load_profile(spec)
