"""A touch panel read straight from Linux's evdev: ``/dev/input/eventN`` (or a FIFO carrying the same records), parsed
into touch frames in the panel's own units.

**The stream.** The kernel writes ``struct input_event {struct timeval time; __u16 type; __u16 code; __s32 value;}``
records (24 bytes on a 64-bit system: two native ``long``s, two ``u16``, one ``s32``; :data:`EVENT`). A panel
speaking the multi-touch protocol B (every current kernel driver; protocol A is obsolete) reports each contact in a
*slot*: ``ABS_MT_SLOT`` picks the slot the next events are for, ``ABS_MT_TRACKING_ID`` gives it a contact (an id
``>= 0``) or ends it (``-1``: a lift), ``ABS_MT_POSITION_X``/``_Y`` and ``ABS_MT_PRESSURE`` its values (sent only
when they change); ``EV_SYN``/``SYN_REPORT`` ends a frame, whose contacts all changed at its time. A single-touch
panel reports ``ABS_X``/``ABS_Y``/``ABS_PRESSURE`` and ``BTN_TOUCH``; a multi-touch panel sends both, and once any
``ABS_MT_*`` event has come the single-touch ones are ignored.

**Lost events.** ``SYN_DROPPED`` means the kernel's buffer for this reader overflowed: the events up to and including
the next ``SYN_REPORT`` are discarded (as the kernel's documentation asks) and every contact is lifted, its values
forgotten; a finger still down is felt again once it touches anew (or, its slot's position being reported again,
once a new contact there is known). Nothing is rendered from a state the reader is unsure of: the plate rests.
On a real device the current slot is asked back (``EVIOCGABS(ABS_MT_SLOT)``); on a FIFO the last one seen is kept.

**Axis ranges.** Panel units become 0..1 through each axis's range. A real evdev node says them itself
(``EVIOCGABS``, as ``evtest`` prints them); a node that is not one (a FIFO, as the tests use: this machine has no
``/dev/uinput``) cannot, and the ranges must be given (the rig's ``[touch] x_range``, ``y_range``,
``pressure_range``, or ``serve --touch-range``). Ranges given win over the kernel's.

**Bounded.** A read takes at most :data:`READ_RECORDS` records; the parser keeps under one record of a partial read,
:data:`MAX_SLOTS` slots (a higher slot is ignored and counted), and a frame of more than :data:`MAX_FRAME_EVENTS`
events without its ``SYN_REPORT`` is treated as a drop.
"""

from __future__ import annotations

import errno
import os
import stat
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from ultraglide.devices.errors import DeviceError

EVENT = struct.Struct("@llHHi")  # struct input_event: time (tv_sec, tv_usec: native longs), type, code, value
EVENT_BYTES = EVENT.size  # 24 on a 64-bit system
EV_SYN, EV_KEY, EV_ABS = 0x00, 0x01, 0x03
SYN_REPORT, SYN_MT_REPORT, SYN_DROPPED = 0, 2, 3
BTN_TOUCH = 0x14A
ABS_X, ABS_Y, ABS_PRESSURE = 0x00, 0x01, 0x18
ABS_MT_SLOT, ABS_MT_POSITION_X, ABS_MT_POSITION_Y = 0x2F, 0x35, 0x36
ABS_MT_TRACKING_ID, ABS_MT_PRESSURE = 0x39, 0x3A
ABS_MAX = 0x3F
MT_CODES = frozenset({ABS_MT_POSITION_X, ABS_MT_POSITION_Y, ABS_MT_TRACKING_ID, ABS_MT_PRESSURE})
MAX_SLOTS = 16  # contacts followed at once (slots 0..15); a hand has 10 fingers
MAX_FRAME_EVENTS = 4096  # events without a SYN_REPORT before the frame is taken as broken
READ_RECORDS = 256  # records taken per read
AXES = ("x", "y", "pressure")
VALUE_RANGE = (-(2**31), 2**31 - 1)  # an axis value is an s32

# ioctl request numbers, asm-generic/ioctl.h's layout (x86, ARM, RISC-V): dir << 30 | size << 16 | type << 8 | nr
_IOC_READ = 2


def _ioc_read(nr: int, size: int) -> int:
    return (_IOC_READ << 30) | (size << 16) | (ord("E") << 8) | nr


def eviocgabs(axis: int) -> int:
    """``EVIOCGABS(axis)``: read an axis's ``struct input_absinfo`` (six s32: value, minimum, maximum, fuzz, flat,
    resolution).

    Examples
    --------
    >>> hex(eviocgabs(ABS_MT_POSITION_X))
    '0x80184575'
    """
    return _ioc_read(0x40 + axis, 24)


def eviocgbit(event_type: int, length: int) -> int:
    """``EVIOCGBIT(event_type, length)``: the bitmask of the codes a device reports for ``event_type``."""
    return _ioc_read(0x20 + event_type, length)


def eviocgname(length: int) -> int:
    """``EVIOCGNAME(length)``: the device's name."""
    return _ioc_read(0x06, length)


class TouchPanelError(DeviceError):
    """A touch panel that cannot be read; one line saying what to do."""


class TouchPanelUsageError(TouchPanelError):
    """A touch panel named wrongly (no such node, not a device, no axis ranges for a FIFO): exit status 2."""

    exit_status = 2


class PanelGone(TouchPanelError):
    """The panel went away: its events ended (a FIFO's writer closed) or the device was unplugged (ENODEV)."""


@dataclass(frozen=True)
class AxisRange:
    """An axis's range in the panel's units (``minimum`` < ``maximum``, both s32), as ``EVIOCGABS`` or evtest say."""

    minimum: int
    maximum: int

    def __post_init__(self) -> None:
        if not (VALUE_RANGE[0] <= self.minimum < self.maximum <= VALUE_RANGE[1]):
            raise TouchPanelUsageError(f"an axis range must be MIN:MAX, whole numbers with MIN < MAX, got "
                                       f"{self.minimum}:{self.maximum}")

    def unit(self, value: float) -> float:
        """``value`` as a share of the range, 0..1 (clamped).

        Examples
        --------
        >>> AxisRange(0, 4095).unit(1023.75)
        0.25
        """
        share = (value - self.minimum) / (self.maximum - self.minimum)
        return 0.0 if share < 0.0 else 1.0 if share > 1.0 else share


@dataclass(frozen=True)
class PanelRanges:
    """The ranges of a panel's axes (``pressure``: None when it measures none) and where they came from."""

    x: AxisRange
    y: AxisRange
    pressure: AxisRange | None = None
    source: str = "given"

    def words(self) -> str:
        """One line: ``x 0..4095, y 0..4095, pressure 0..255 (the kernel's)``."""
        parts = [f"{axis} {r.minimum}..{r.maximum}" for axis, r in (("x", self.x), ("y", self.y),
                                                                    ("pressure", self.pressure)) if r is not None]
        return f"{', '.join(parts)}{'' if self.pressure else ', no pressure'} ({self.source})"


def parse_range(text: str) -> tuple[str, AxisRange]:
    """One ``--touch-range`` value: ``AXIS=MIN:MAX`` with AXIS ``x``, ``y`` or ``pressure``, in panel units.

    Parameters
    ----------
    text : str
        The option's value.

    Returns
    -------
    (str, AxisRange)
        The axis and its range.

    Raises
    ------
    TouchPanelUsageError
        One line, for anything else.

    Examples
    --------
    >>> parse_range("x=0:4095")
    ('x', AxisRange(minimum=0, maximum=4095))
    """
    axis, sep, span = text.partition("=")
    low, colon, high = span.partition(":")
    try:
        if not sep or not colon or axis.strip() not in AXES:
            raise ValueError
        return axis.strip(), AxisRange(int(low), int(high))
    except (ValueError, TouchPanelUsageError):
        raise TouchPanelUsageError(f"--touch-range {text[:60]!r}: give AXIS=MIN:MAX, AXIS one of x, y, pressure, "
                                   "MIN < MAX whole numbers in the panel's units (evtest prints them)") from None


def given_ranges(options: list[str], rig_ranges: dict | None = None) -> PanelRanges | None:
    """The ranges given by a rig and by ``--touch-range`` options (which win, axis by axis).

    Parameters
    ----------
    options : list of str
        ``--touch-range`` values, ``AXIS=MIN:MAX`` in panel units.
    rig_ranges : dict or None
        The rig's ``[touch]`` ranges, ``{"x": (min, max), ...}`` (:attr:`devices.rig.TouchPanel.axis_ranges`).

    Returns
    -------
    PanelRanges or None
        None when no range is given at all.

    Raises
    ------
    TouchPanelUsageError
        A bad option, or x without y (or y without x).

    Examples
    --------
    >>> given_ranges(["y=0:2047"], {"x": (0, 4095)}).words()
    'x 0..4095, y 0..2047, no pressure (the rig and --touch-range)'
    """
    ranges, source = {}, []
    for axis, span in (rig_ranges or {}).items():
        if span is not None:
            ranges[axis] = AxisRange(*span)
            source = ["the rig"]
    for text in options:
        axis, span = parse_range(text)
        ranges[axis] = span
        if "--touch-range" not in source:
            source.append("--touch-range")
    if not ranges:
        return None
    if "x" not in ranges or "y" not in ranges:
        missing = "x" if "x" not in ranges else "y"
        raise TouchPanelUsageError(f"the touch panel's {missing} range is not given: give both x and y "
                                   f"(--touch-range {missing}=MIN:MAX, or [touch] {missing}_range in the rig)")
    return PanelRanges(ranges["x"], ranges["y"], ranges.get("pressure"), " and ".join(source))


@dataclass(frozen=True)
class Contact:
    """A contact's change in one frame: ``slot`` (0 for a single-touch panel), ``phase`` ``down``, ``move`` or ``up``,
    its position in panel units, its pressure (panel units, None when not reported) and the frame's kernel time
    (s, the ``SYN_REPORT``'s timestamp)."""

    slot: int
    phase: str
    x: int
    y: int
    pressure: int | None
    t_s: float


@dataclass(frozen=True)
class Frame:
    """What one ``SYN_REPORT`` changed; ``resynced``: this frame ends a drop (``SYN_DROPPED``): every contact lifted."""

    t_s: float
    contacts: tuple[Contact, ...]
    resynced: bool = False


@dataclass
class ParserCounts:
    """What the parser met: records, frames, drops (``SYN_DROPPED``, or a frame too long), slots beyond
    :data:`MAX_SLOTS`, protocol-A reports (``SYN_MT_REPORT``: ignored)."""

    records: int = 0
    frames: int = 0
    drops: int = 0
    slots_ignored: int = 0
    type_a_reports: int = 0


@dataclass
class _Slot:
    id: int = -1  # the contact the kernel has in it, as far as we know (-1: none)
    x: int | None = None
    y: int | None = None
    pressure: int | None = None
    felt: int = -1  # the contact reported down (and not yet up)
    last: tuple = (0, 0, None)  # (x, y, pressure) last reported


@dataclass
class EventParser:
    """input_event records in, :class:`Frame` s out: :meth:`feed` takes any bytes (a partial record is kept for the
    next call) and returns the frames they completed. ``current_slot``: asked after a drop for the slot the kernel
    is at (a real device's ``EVIOCGABS(ABS_MT_SLOT)``); None keeps the last one seen.

    Examples
    --------
    >>> parser = EventParser()
    >>> records = [(3, 0x39, 7), (3, 0x35, 100), (3, 0x36, 200), (0, 0, 0)]
    >>> frames = parser.feed(b"".join(EVENT.pack(5, 250000, *r) for r in records))
    >>> frames[0].contacts
    (Contact(slot=0, phase='down', x=100, y=200, pressure=None, t_s=5.25),)
    """

    current_slot: Callable[[], int | None] | None = None
    counts: ParserCounts = field(default_factory=ParserCounts)

    def __post_init__(self) -> None:
        self._partial = b""
        self._slots = [_Slot() for _ in range(MAX_SLOTS)]
        self._slot: int | None = 0
        self._multi = False
        self._single = _Slot()  # a single-touch panel's one contact (id 0 while BTN_TOUCH is down)
        self._dropping = False
        self._frame_events = 0

    def feed(self, data: bytes) -> list[Frame]:
        """The frames completed by ``data`` (bytes of input_event records, any split)."""
        data = self._partial + bytes(data)
        whole = len(data) - len(data) % EVENT_BYTES
        self._partial = data[whole:]
        frames = []
        for sec, usec, kind, code, value in EVENT.iter_unpack(data[:whole]):
            self.counts.records += 1
            if self._dropping:
                if kind == EV_SYN and code == SYN_REPORT:
                    self._dropping = False
                    frames.append(self._resync(sec + usec * 1e-6))
                continue
            self._frame_events += 1
            if kind == EV_SYN:
                if code == SYN_REPORT:
                    frame = self._frame(sec + usec * 1e-6)
                    if frame.contacts:
                        frames.append(frame)
                elif code == SYN_DROPPED:
                    self._drop()
                elif code == SYN_MT_REPORT:
                    self.counts.type_a_reports += 1
            elif kind == EV_ABS:
                self._absolute(code, value)
            elif kind == EV_KEY and code == BTN_TOUCH:
                self._single.id = 0 if value else -1
            if self._frame_events > MAX_FRAME_EVENTS:
                self._drop()
        return frames

    def _drop(self) -> None:
        self.counts.drops += 1
        self._dropping = True

    def _absolute(self, code: int, value: int) -> None:
        if code == ABS_MT_SLOT:
            self._slot = value if 0 <= value < MAX_SLOTS else None
            if self._slot is None:
                self.counts.slots_ignored += 1
            return
        if code in MT_CODES:
            self._multi = True
            if self._slot is None:
                return
            slot = self._slots[self._slot]
            if code == ABS_MT_TRACKING_ID:
                slot.id = value if value >= 0 else -1
            elif code == ABS_MT_POSITION_X:
                slot.x = value
            elif code == ABS_MT_POSITION_Y:
                slot.y = value
            else:
                slot.pressure = value
        elif code == ABS_X:
            self._single.x = value
        elif code == ABS_Y:
            self._single.y = value
        elif code == ABS_PRESSURE:
            self._single.pressure = value

    def _frame(self, t_s: float) -> Frame:
        self.counts.frames += 1
        self._frame_events = 0
        contacts: list[Contact] = []
        if self._multi:
            if self._single.felt != -1:  # a panel that turned out multi-touch: its single-touch contact ends
                contacts.append(Contact(0, "up", *self._single.last, t_s))
                self._single = _Slot()
            for number, slot in enumerate(self._slots):
                _changes(number, slot, t_s, contacts)
        else:
            _changes(0, self._single, t_s, contacts)
        return Frame(t_s, tuple(contacts))

    def _resync(self, t_s: float) -> Frame:
        """After a drop: every contact felt is lifted and every value forgotten."""
        self._frame_events = 0
        contacts = []
        for number, slot in enumerate([*self._slots, self._single]):
            if slot.felt != -1:
                contacts.append(Contact(0 if slot is self._single else number, "up", *slot.last, t_s))
        self._slots = [_Slot() for _ in range(MAX_SLOTS)]
        self._single = _Slot()
        if self.current_slot is not None:
            slot = self.current_slot()
            if slot is not None:
                self._slot = slot if 0 <= slot < MAX_SLOTS else None
        return Frame(t_s, tuple(contacts), resynced=True)


def _changes(number: int, slot: _Slot, t_s: float, contacts: list) -> None:
    """A slot's change over a frame, appended to ``contacts``: an end (its contact gone or replaced), a start (a
    contact whose position is known), or a move."""
    if slot.felt != -1 and slot.id != slot.felt:
        contacts.append(Contact(number, "up", *slot.last, t_s))
        slot.felt = -1
    if slot.id == -1 or slot.x is None or slot.y is None:
        return
    now = (slot.x, slot.y, slot.pressure)
    if slot.felt == -1:
        slot.felt = slot.id
        contacts.append(Contact(number, "down", *now, t_s))
    elif now != slot.last:
        contacts.append(Contact(number, "move", *now, t_s))
    slot.last = now


class PanelReader:
    """A touch panel's node opened for reading, non-blocking: a real evdev device (its axis ranges asked of the
    kernel) or a FIFO carrying input_event records (its ranges given). :meth:`read` returns the frames that have
    arrived; :attr:`fd` is for a loop's ``add_reader``.

    Parameters
    ----------
    path : str
        ``/dev/input/eventN`` (``/dev/input/by-id/...`` links too) or a FIFO.
    ranges : PanelRanges or None
        Axis ranges given (the rig's, ``--touch-range``): needed for a FIFO, and winning over a device's own.

    Raises
    ------
    TouchPanelUsageError
        No such node, not a device nor a FIFO, a character device that is not evdev, a FIFO without ranges, a device
        without position axes (exit status 2).
    TouchPanelError
        The node cannot be opened (permission: the ``input`` group).
    """

    def __init__(self, path: str, ranges: PanelRanges | None = None):
        self.path = os.fspath(path)
        try:
            mode = os.stat(self.path).st_mode
        except FileNotFoundError:
            raise TouchPanelUsageError(f"--touch-panel {self.path}: no such file; the panels are listed by "
                                       "ls -l /dev/input/by-id/ and evtest") from None
        except OSError as error:
            raise TouchPanelError(f"--touch-panel {self.path}: {error.strerror}") from None
        if stat.S_ISCHR(mode):
            self.kind = "evdev"
        elif stat.S_ISFIFO(mode):
            self.kind = "fifo"
        else:
            raise TouchPanelUsageError(f"--touch-panel {self.path}: not a device nor a FIFO: give the panel's evdev "
                                       "node (/dev/input/eventN; evtest lists them)")
        if self.kind == "fifo" and ranges is None:
            raise TouchPanelUsageError(f"--touch-panel {self.path} is a FIFO, not an evdev device, so its axis ranges "
                                       "cannot be asked: give them (--touch-range x=MIN:MAX --touch-range y=MIN:MAX, "
                                       "or [touch] x_range and y_range in the rig)")
        try:
            self.fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        except PermissionError:
            raise TouchPanelError(f"--touch-panel {self.path}: permission denied: add yourself to the input group "
                                  "(sudo usermod -aG input $USER, then log in again)") from None
        except OSError as error:
            raise TouchPanelError(f"--touch-panel {self.path}: cannot open it: {error.strerror}") from None
        try:
            self.name = ""
            if self.kind == "evdev":
                self.name, kernel = self._ask_kernel()
                ranges = ranges or kernel
            self.ranges = ranges
        except BaseException:
            os.close(self.fd)
            raise
        self.parser = EventParser(self._kernel_slot if self.kind == "evdev" else None)
        self.closed = False

    def _ask_kernel(self) -> tuple[str, PanelRanges]:
        import fcntl

        try:
            bits = fcntl.ioctl(self.fd, eviocgbit(EV_ABS, (ABS_MAX + 8) // 8), bytes((ABS_MAX + 8) // 8))
            name = fcntl.ioctl(self.fd, eviocgname(256), bytes(256)).split(b"\0", 1)[0].decode("utf-8", "replace")
        except OSError as error:
            raise TouchPanelUsageError(f"--touch-panel {self.path}: a character device but not an evdev one "
                                       f"({error.strerror}): give /dev/input/eventN") from None

        def has(code: int) -> bool:
            return bool(bits[code // 8] >> (code % 8) & 1)

        if has(ABS_MT_POSITION_X) and has(ABS_MT_POSITION_Y):
            x, y, pressure = ABS_MT_POSITION_X, ABS_MT_POSITION_Y, ABS_MT_PRESSURE
        elif has(ABS_X) and has(ABS_Y):
            x, y, pressure = ABS_X, ABS_Y, ABS_PRESSURE
        else:
            raise TouchPanelUsageError(f"--touch-panel {self.path} ({name}) reports no position axes: it is not a "
                                       "touch panel (evtest shows what it reports)")
        ranges = [self._absinfo(code)[1:3] if code is not None and has(code) else None for code in (x, y, pressure)]
        return name, PanelRanges(AxisRange(*ranges[0]), AxisRange(*ranges[1]),
                                 AxisRange(*ranges[2]) if ranges[2] and ranges[2][1] > ranges[2][0] else None,
                                 "the kernel's")

    def _absinfo(self, axis: int) -> tuple[int, ...]:
        import fcntl

        return struct.unpack("6i", fcntl.ioctl(self.fd, eviocgabs(axis), bytes(24)))

    def _kernel_slot(self) -> int | None:
        try:
            return self._absinfo(ABS_MT_SLOT)[0]
        except OSError:
            return None

    def words(self) -> str:
        """One line: the node, what it is, its ranges."""
        what = f"evdev device {self.name!r}" if self.kind == "evdev" else "a FIFO of evdev records"
        return f"touch panel {self.path}: {what}; {self.ranges.words()}"

    def read(self) -> list[Frame]:
        """The frames that arrived (none if nothing did: the node is non-blocking).

        Raises
        ------
        PanelGone
            Its events ended (end of file: a FIFO's writer closed) or the device went (ENODEV: unplugged).
        """
        try:
            data = os.read(self.fd, READ_RECORDS * EVENT_BYTES)
        except BlockingIOError:
            return []
        except OSError as error:
            if error.errno in (errno.ENODEV, errno.EIO):
                raise PanelGone(f"the touch panel {self.path} went away (unplugged: {error.strerror})") from None
            raise TouchPanelError(f"the touch panel {self.path} cannot be read: {error.strerror}") from None
        if not data:
            raise PanelGone(f"the touch panel {self.path} went away (its events ended)")
        return self.parser.feed(data)

    def close(self) -> None:
        """Close the node (once; again does nothing)."""
        if not self.closed:
            self.closed = True
            os.close(self.fd)
