"""The serial plate driver: streams amplitude setpoints to plate-driver firmware (docs/protocol.md).

A writer thread pulls the envelope from its source at the control rate and sends it in batches
(every ``batch_s``); pyserial's ReaderThread decodes telemetry and acknowledgements. When the port
vanishes or the device stops answering, the driver counts it, keeps pulling from the source (the
renderer keeps its clock), and reconnects with exponential backoff when the port is back. On every
way out, error paths included, it sends zero amplitude and disable while the link works. It counts
every fault the device reports over the whole run (from the device's fault counters, across
reconnections), clears the device's latched bits, and keeps what happened and when: :meth:`report`
says it in words and gives the exit status it earns (:mod:`ultraglide.devices.serial.run_report`).

**The device's limits bind.** At each handshake the host takes the smaller of the profile's and the
device's amplitude limit (and drive ceiling), binds the output stage's limiter to them, and scales
setpoint codes by the device's own full scale; :attr:`notes` says so when they differ from the profile.

**Timing.** While streaming, the writer keeps the plate's jitter buffer at its target depth: it sends
``lead`` values (the device's prefill, 10 ms, plus one frame) ahead of its clock, so sample k of the
stream plays at ``start + k / rate``. A stream that (re)starts sends the whole lead in its first frame,
which the device plays on arrival. After a stall of the host long enough for the plate to run dry, the
writer skips ahead (the device counts the skipped values as lost) instead of sending its backlog, so the
latency once streaming resumes is the lead again, not the stall. A v3 device reports its buffer's depth
in telemetry: its median over 0.2 s more than 5 ms off its target (the plate's clock drifting from the
host's, its playback restarted late) moves the lead by the difference; a few frames deep for a moment (the
plate catching up a stall of its own, reading a backlog late) do not. The source is told when its values play
on the plate (``pull``'s ``now_s``): the host's clock, moved by what the lead was moved by. A wake's ENABLE 1
goes unacknowledged; telemetry that says the plate is still off 0.1 s later has it sent again.

The carrier can change while it runs: :meth:`set_carrier` (acknowledged; the plate sweep uses it),
or a :class:`~ultraglide.devices.characterisation.resonance.ResonanceTracker` given as ``tracker``, which is fed every
telemetry frame (carrier, measured amplitude, mean commanded amplitude since the previous frame) and
whose carrier the writer thread sends when it changes (unacknowledged: telemetry confirms it).

The port is opened exclusively (a ``flock``, which pyserial's ``exclusive`` takes and which holds on
pseudo-terminals too, plus ``TIOCEXCL`` for programs that do not lock): a second driver on the same
port is refused in one line. A setpoint rate the link cannot carry at its baud rate is refused too.

**The link decides the stream.** Given a ``stream`` (a :class:`~.link.StreamPlan`, which
:func:`~ultraglide.devices.urls.open_device` fits to what the device says its link carries), the driver streams
at its rate in its frames and says which and why in :attr:`notes` (and ``status()["stream"]``).

Example::

    plate = SerialPlate("/dev/ttyACM0", profile)
    plate.start(source)      # a devices.source.BlockSource of µm setpoints
    ...
    plate.stop()             # ramps down, then zero and disable
    plate.report().lines     # what happened, in words; .exit_status
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

from ultraglide.devices import protocol as p
from ultraglide.devices.characterisation.resonance import ResonanceTracker
from ultraglide.devices.errors import DeviceError
from ultraglide.devices.output.source import BlockSource, ramp_down
from ultraglide.devices.output.stage import output_stage
from ultraglide.devices.profiles import PlateProfile
from ultraglide.devices.serial.handshake import Limits
from ultraglide.devices.serial.link import SILENCE_S, Pacing, SerialCounters, StreamPlan, check_link_budget
from ultraglide.devices.serial.locks import DriverLocks
from ultraglide.devices.serial.report import RunAccount, RunFigures
from ultraglide.devices.serial.run_report import RunReport
from ultraglide.devices.serial.session import Session
from ultraglide.devices.serial.streamer import Streamer
from ultraglide.devices.serial.telemetry import Intake
from ultraglide.devices.serial.transport import Transport


class SerialPlate:
    """A plate driver on a serial port (any pyserial URL: a device path, ``loop://``, …), composed of its parts:
    :attr:`transport` (the port, framing, reads and writes), :attr:`session` (the connection and its state),
    :attr:`intake` (what comes back), :attr:`streamer` (the writer thread) and :attr:`account` (the run's
    record); their locks and the order they may be taken in are in :mod:`.locks`."""

    signal = "control"

    def __init__(self, port: str, profile: PlateProfile, control_rate_hz: int = 12000, carrier_hz: float | None = None,
                 baudrate: int = 921600, batch_s: float | None = None, ack_timeout_s: float = p.HOST_ACK_TIMEOUT_S,
                 tracker: ResonanceTracker | None = None, check_budget: bool = True, silence_s: float = SILENCE_S,
                 amplitude_loop: bool = False, stream: StreamPlan | None = None):
        self.port, self.profile, self.tracker = port, profile, tracker
        if stream is not None:  # the stream fitted to the device's link (it overrides the rate and frame given)
            control_rate_hz, batch_s = stream.rate_hz, stream.batch_s
        self.stream = stream
        self.rate_hz = int(control_rate_hz)
        if check_budget and "://" not in port:  # URL transports (loop://, socket://) have no baud rate
            check_link_budget(port, baudrate, self.rate_hz)
        self.baudrate = baudrate
        self.batch_s = batch_s or p.batch_s_for(baudrate, self.rate_hz)  # s between SETPOINTS frames
        self.ack_timeout_s = ack_timeout_s
        self.silence_s = silence_s  # no telemetry, or no room for a frame, for this long: the device is gone
        self.pacing = Pacing.of(self.rate_hz, self.batch_s)
        self.counters = SerialCounters()
        self.locks = DriverLocks()
        self.account = RunAccount(self.locks.account)
        self.transport = Transport(port, baudrate, silence_s, self.rate_hz, self.locks, self.counters,
                                   on_frame=self._frame, on_bad_frames=self._bad_frames, on_lost=self._lost)
        carrier = tracker.carrier_hz if tracker is not None else (carrier_hz or profile.resonance_hz)
        self.session = Session(port, profile, self.rate_hz, carrier, self.transport, self.locks, self.account,
                               self.counters, ack_timeout_s, amplitude_loop,
                               has_baseline=lambda: self.intake.has_baseline, bound=self._bound, fresh=self._fresh,
                               batch_s=self.batch_s)
        self.intake = Intake(self.session, self.account, self.counters, self.locks, self.pacing, tracker,
                             self.transport.kind_of)
        self.streamer = Streamer(self.session, self.transport, self.intake, self.account, self.counters,
                                 self.pacing, silence_s, lost=self._lost, tracker=tracker)
        self._source: BlockSource | None = None
        self._thread: threading.Thread | None = None

    # ---- what the parts know, by name ---------------------------------------------------------
    carrier_hz = property(lambda self: self.session.carrier_hz,
                          lambda self, hz: setattr(self.session, "carrier_hz", float(hz)),
                          doc="The carrier the plate plays (Hz); set before :meth:`start`, or use :meth:`set_carrier`.")
    device = property(lambda self: self.session.state.device, doc="The device's HELLO_REPLY (None before one).")
    notes = property(lambda self: self.session.notes, doc="Where the device's facts bind the host, one line each.")
    limit_um_pp = property(lambda self: self.session.limits.limit_um_pp, doc="The limit that binds (µm p-p).")
    max_drive_um_pp = property(lambda self: self.session.limits.max_drive_um_pp, doc="The drive ceiling (µm p-p).")
    full_scale_um_pp = property(lambda self: self.session.limits.full_scale_um_pp,
                                doc="Full scale codes are scaled by (µm p-p): the device's once it has spoken.")
    loop_on = property(lambda self: self.session.state.loop_on, doc="The device's amplitude loop runs.")
    telemetry = property(lambda self: self.intake.telemetry, doc="The last TELEMETRY frame (this connection).")
    telemetry_frames = property(lambda self: self.intake.frames, doc="TELEMETRY frames taken over the run.")
    sensors = property(lambda self: self.intake.sensors, doc="The last SENSORS frame.")
    sensors_frames = property(lambda self: self.intake.sensors_frames, doc="SENSORS frames taken over the run.")
    sensor_errors = property(lambda self: self.intake.sensor_errors, doc="Sensor listeners that raised.")
    lead = property(lambda self: self.pacing.lead,
                    doc="Values the writer keeps sent ahead of its clock: the device's prefill plus a frame.")
    buffer_lasts_s = property(lambda self: self.pacing.buffer_lasts_s,
                              doc="How long the plate's buffer lasts after a frame (s): a frame later is late.")

    def hello(self) -> p.HelloReply | None:
        """What the device said of itself in this connection's handshake (None before one)."""
        return self.session.state.device

    def next_telemetry(self, timeout_s: float | None = None) -> p.Telemetry:
        """Wait for the next TELEMETRY frame and return it; DeviceError if none comes within ``timeout_s``
        (default: the ACK timeout)."""
        timeout_s = self.ack_timeout_s if timeout_s is None else timeout_s
        telemetry = self.intake.next(timeout_s)
        if telemetry is None:
            raise DeviceError(f"{self.port}: no telemetry from the plate driver for {timeout_s:g} s")
        return telemetry

    def fault_counts(self) -> dict[str, int]:
        """Each fault the device can report, by name, with how often it happened over this run."""
        return self.intake.fault_counts()

    def add_sensor_listener(self, listener) -> None:
        """Call ``listener(sensors)`` with each SENSORS frame (a :class:`protocol.Sensors`), on the reader thread:
        it must return quickly. A listener that raises is counted (``sensor_errors``) and left out from then on."""
        self.intake.add_sensor_listener(listener)

    def add_clock_listener(self, listener) -> None:
        """Call ``listener(samples, asked_s, received_s)`` with each CLOCK_REPLY, on the reader thread: the device's
        sensor clock (samples, numbered as SENSORS' and wrapping at 2**32; never ahead of its clock, at most
        ``MAX_CLOCK_LAG_MS`` behind) when it took a CLOCK request written at ``asked_s`` and answered by
        ``received_s`` (perf_counter s). With a listener, the writer asks every ``CLOCK_EVERY_S`` while it streams,
        where the device states its clock (``FEATURE_CLOCK_STATED``); elsewhere nothing is asked and nothing comes."""
        self.intake.add_clock_listener(listener)

    def command(self, kind: int, payload: bytes = b"", timeout_s: float | None = None) -> None:
        """Send a command frame and wait for its ACK; DeviceError on a NAK or silence (a test's or a tool's)."""
        self.session.command(kind, payload, timeout_s)

    def send(self, kind: int, payload: bytes = b"") -> int:
        """Send one frame, its answer not awaited; its seq (a test's or a tool's)."""
        return self.session.send(kind, payload)

    def sweeping(self) -> None:
        """The carrier is to be swept (``plate sweep``): the plate's amplitude off resonance is the measurement, not
        a plate that fails to follow what it is sent (devices/serial/follow.py), so it is not judged."""
        self.account.follow.judging = False

    def set_carrier(self, carrier_hz: float) -> None:
        """Change the carrier now (Hz) and wait for the device's ACK; DeviceError if it refuses or is gone."""
        self.session.set_carrier(carrier_hz)
        self.counters.carrier_changes += 1

    # ---- the parts' callbacks -------------------------------------------------------------------
    def _frame(self, frame: p.Frame) -> None:
        self.intake.frame(frame)

    def _bad_frames(self, count: int, crc_errors: int, framing_errors: int) -> None:
        self.counters.bad_frames += count
        self.account.bad_frames(crc_errors, framing_errors)

    def _lost(self, cause: str) -> None:
        """The link failed (reader or writer thread): the plate is lost until a reconnection."""
        connected = self.session.state.connected
        if connected.is_set():
            connected.clear()
            self.counters.disconnects += 1
            self.account.outage(cause, self.counters.setpoints_discarded)

    def _bound(self, limits: Limits) -> None:
        stage = self._source
        if stage is not None and hasattr(stage, "limiter"):
            stage.limiter.bind(limits.limit_um_pp, limits.max_drive_um_pp)

    def _fresh(self) -> None:
        self.intake.telemetry = None

    def _rest(self) -> None:
        """The end of the run: zero amplitude and disable while the link still works, exactly once."""
        if not self.account.rest_once():
            return
        session = self.session
        if session.state.device is None:  # never connected: nothing to rest (a failed handshake rested what answered)
            return
        if not self.transport.is_open:
            session.rest_failure = "the link was down"
            return
        if session.rest_now():
            session.rest_failure = None

    # ---- the run --------------------------------------------------------------------------------
    def start(self, source: BlockSource) -> None:
        """Connect (handshake, carrier, enable) and start streaming; raises DeviceError if it cannot."""
        self.profile.check_carrier(self.carrier_hz)
        self._source = output_stage(source, self.profile, self.signal, self.rate_hz)
        self.account.started = time.perf_counter()
        self.session.connect()
        if self.stream is not None:  # said after where the device's limits bind
            device = self.session.state.device
            if self.stream.link_bytes_per_s == 0 and device is not None and device.states_link:
                self.stream = replace(self.stream, link_bytes_per_s=device.link_bytes_per_s)  # the URL's stream
            self.session.notes.append(self.stream.line(self.port))
        self._thread = threading.Thread(target=self.streamer.run, args=(self._source, self._rest), name="serial-plate",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Ramp down through the source, then send zero and disable and close the port."""
        if self._source is not None and self._thread is not None and self._thread.is_alive():
            ramp_down(self._source, self._thread.is_alive)
        self.streamer.stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            if self._thread.is_alive():  # stuck (a write that never returns): rest from here, once
                self._rest()
        else:
            self._rest()
        self.session.disconnect()

    def report(self) -> RunReport:
        """The run so far in words, with the exit status it earns (see :mod:`.run_report`)."""
        return self.account.report(RunFigures(self.counters, self.fault_counts(), self.intake.link_run, self.pacing,
                                              self.intake.depth.worst, self.session.rest_failure))

    def status(self) -> dict:
        """The driver's counters, the device's facts and the run's report, as JSON-ready values."""
        c, t, state = self.counters, self.telemetry, self.session.state
        faults = self.fault_counts()
        output = "cut by the device" if state.cut else ("streaming" if state.output_on else "idle (disabled)")
        return {
            "device": f"serial:{self.port}", "connected": state.connected.is_set(),
            "frames_sent": c.frames_sent, "setpoints_sent": c.setpoints_sent, "disconnects": c.disconnects,
            "reconnects": c.reconnects, "silences": c.silences, "bad_frames_received": c.bad_frames,
            "naks_received": c.naks, "send_stalls": c.send_stalls, "host_stalls": c.host_stalls,
            "write_timeouts": c.write_timeouts,
            "late_frames": c.late_frames, "depth_corrections": c.depth_corrections,
            "setpoints_not_sent": c.setpoints_discarded, "setpoints_skipped": c.setpoints_skipped,
            "carrier_hz": round(self.carrier_hz, 2), "carrier_changes": c.carrier_changes,
            "output": output, "idle_rests": c.idle_rests, "idle_wakes": c.idle_wakes, "reenables": c.reenables,
            "protocol_version": None if state.device is None else state.device.version,
            "device_name": None if state.device is None else state.device.name,
            "limit_um_pp": self.limit_um_pp, "max_drive_um_pp": self.max_drive_um_pp,
            "device_full_scale_um_pp": self.full_scale_um_pp, "notes": list(self.notes),
            "stream": (self.stream.as_dict() if self.stream is not None else
                       {"rate_hz": self.rate_hz, "frame_ms": round(self.batch_s * 1000, 3), "chosen_by": "caller"}),
            "measured_um_pp": None if t is None else t.measured_um_pp,
            "device_frames_ok": None if t is None else t.frames_ok,
            "device_crc_errors": None if t is None else t.crc_errors,
            "device_lost_setpoints": None if t is None else t.lost_setpoints,
            "device_late_setpoints": None if t is None else t.late_setpoints,
            "faults": faults,
            "device_faults": [name for name, count in faults.items() if count],
            "report": self.report().as_dict(),
            "values_not_believed": self.account.field_check.counts(),  # frames by "FRAME field" (protocol/ranges.py)
            **({"tracking": self.tracker.summary()} if self.tracker is not None else {}),
        }
