"""The touch panel the engine reads itself (``ultraglide serve --touch-panel PATH``): the clients only place sprites.

The panel's node (:class:`devices.touch.evdev.PanelReader`: a Linux evdev device, or a FIFO of its records) is read
on the service's loop (``add_reader``: no thread, the same loop that takes clients' touches, so the two never race).
Each contact of each frame is mapped as the demo maps SDL's fingers, through the rig's ``[touch]``
(:class:`devices.rig.TouchPanel`): the panel's units become 0..1 through its axis ranges, are turned, flipped and
placed on its ``area_mm`` of the display, which is taken to be the active view from its top-left corner (without an
``area_mm``, the panel covers the whole view). Its pressure, through the pressure range, times the rig's
``pressure_full_scale_n`` is the finger's force (without both, the engine's default force). The contact then goes
the way a client's ``touch`` goes (:meth:`Service.pointer`): which finger drives is the service's rule (the rig's
``drives``, or ``touches.set``), and ``touch.seen`` reports it.

Time: a frame's kernel timestamp is put on the engine's clock by the least offset seen between it and its arrival
(a constant offset, whatever the kernel's clock, cancels; a slow delivery does not pull it later); a timestamp
that would put a touch more than :data:`STEP_S` before it arrived (a wall clock stepped back) resets the offset.

A panel that goes away (its events end, or the device is unplugged) lifts its fingers at once (the plate ramps to
rest) and ends the service, which says so in one line and exits 1.
"""

from __future__ import annotations

import time

from ultraglide.apps.service.server import MIN_PRESSED_FORCE_N, Service, Session
from ultraglide.devices.rig import TouchPanel
from ultraglide.devices.touch.evdev import PanelReader, TouchPanelError

from ultraglide.errors import describe

STEP_S = 1.0  # a kernel timestamp this far behind its arrival: the clock stepped, the offset starts afresh


class PanelFeed:
    """A touch panel's contacts into the service's pointers.

    Parameters
    ----------
    service : Service
        The service whose pointers the panel's contacts become.
    reader : PanelReader
        The panel's node, open.
    panel : TouchPanel or None
        The rig's ``[touch]``: mapping, pressure scale (None: the whole view, no pressure scale).
    """

    def __init__(self, service: Service, reader: PanelReader, panel: TouchPanel | None = None):
        self.service = service
        self.reader = reader
        self.panel = panel or TouchPanel()
        self.session = Session(None, 0, role="panel", client=f"touch panel {reader.path}")
        self.gone: str | None = None  # why the panel ended, one line
        self.contacts = 0
        self.resyncs = 0
        self._offset_s: float | None = None
        self._loop = None

    def start(self, loop) -> None:
        """Read the panel on ``loop`` (an asyncio loop), from now on; the service refuses clients' touches."""
        self.service.touch_panel = self.reader.path
        self._loop = loop
        loop.add_reader(self.reader.fd, self._readable)

    def stop(self) -> None:
        """Stop reading: its fingers lifted, the node closed."""
        if self._loop is not None and not self.reader.closed:
            self._loop.remove_reader(self.reader.fd)
        self.service._lift(time.perf_counter(), self.session)
        self.reader.close()

    def _readable(self) -> None:
        received_s = time.perf_counter()
        try:
            frames = self.reader.read()
        except TouchPanelError as error:  # its events ended, it was unplugged, or it cannot be read
            self.gone = describe(error)
            self.stop()
            return
        for frame in frames:
            self.resyncs += frame.resynced
            t_s = self._engine_time(frame.t_s, received_s)
            for contact in frame.contacts:
                self._contact(contact, t_s, received_s)

    def _engine_time(self, kernel_s: float, received_s: float) -> float:
        offset = received_s - kernel_s
        if self._offset_s is None or offset < self._offset_s or offset - self._offset_s > STEP_S:
            self._offset_s = offset
        return min(kernel_s + self._offset_s, received_s)

    def _contact(self, contact, t_s: float, received_s: float) -> None:
        service = self.service
        view = service.views[service.active_view]
        ranges = self.reader.ranges
        x_mm, y_mm = self.panel.to_mm(ranges.x.unit(contact.x), ranges.y.unit(contact.y),
                                      (view.width_mm, view.height_mm))
        force = None
        if contact.pressure is not None and ranges.pressure is not None:
            force = self.panel.force_n(ranges.pressure.unit(contact.pressure))
            if force is not None:
                force = max(MIN_PRESSED_FORCE_N, force)
        self.contacts += 1
        service.pointer(self.session, view.name, contact.slot, contact.phase, x_mm, y_mm, force, None, t_s)

    def summary(self) -> dict:
        """What the panel did, for the final status: its contacts, frames, drops, and why it ended (or None)."""
        counts = self.reader.parser.counts
        return {"path": self.reader.path, "contacts": self.contacts, "frames": counts.frames, "drops": counts.drops,
                "slots_ignored": counts.slots_ignored, "gone": self.gone}
