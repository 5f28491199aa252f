"""The plate driver's handshake: HELLO, the device's version, carrier, rates and limits, and binding the
host to them."""

from __future__ import annotations

import math

from ultraglide.devices import protocol as p
from ultraglide.devices.errors import DeviceError


class Handshake:
    """The handshake and the device's limits bound: a part of :class:`~ultraglide.devices.serial.plate.SerialPlate`."""

    def _handshake(self) -> p.HelloReply:
        """HELLO, and the device's answer: its HELLO_REPLY (checked), or a NAK or silence reported in one line."""
        with self._reply:
            self._hello = None
        seq = self._send(p.HELLO, p.hello_payload(), awaited=True)
        try:
            with self._reply:
                if not self._reply.wait_for(lambda: self._hello is not None or seq in self._answers,
                                            self.ack_timeout_s):
                    raise DeviceError(f"{self.port}: no answer to the handshake; is a plate driver there, "
                                      f"speaking ultraglide protocol v{p.PROTOCOL_VERSION}?")
                raw, reason = self._hello, self._answers.get(seq)
        finally:
            with self._reply:
                self._awaiting.discard(seq)
                self._answers.pop(seq, None)
        if raw is None:
            raise DeviceError(f"{self.port}: the plate driver refused the handshake (HELLO: "
                              f"{p.NAK_REASONS.get(reason, f'reason {reason}')}); it does not speak ultraglide "
                              f"protocol v{p.PROTOCOL_VERSION} as docs/protocol.md describes")
        return self._check_device(raw)

    def _check_device(self, raw: bytes) -> p.HelloReply:
        """The device's HELLO_REPLY, if it speaks our version and can play what we will send."""
        try:
            version = p.hello_reply_version(raw)
            if version not in p.SUPPORTED_VERSIONS:
                speaks = " or ".join(f"v{v}" for v in p.SUPPORTED_VERSIONS)
                raise DeviceError(f"{self.port}: the plate driver speaks protocol v{version}; this ultraglide "
                                  f"speaks {speaks}: update the firmware (see docs/protocol.md)")
            hello = p.parse_hello_reply(raw)
        except p.ProtocolError as error:
            raise DeviceError(f"{self.port}: the plate driver's handshake reply is malformed ({error})") from None
        if not hello.carrier_min_hz <= self.carrier_hz <= hello.carrier_max_hz:
            raise DeviceError(f"{self.port}: carrier {self.carrier_hz:g} Hz is outside what the plate driver "
                              f"accepts, {hello.carrier_min_hz:g}-{hello.carrier_max_hz:g} Hz")
        if not hello.min_setpoint_rate_hz <= self.rate_hz <= hello.max_setpoint_rate_hz:
            raise DeviceError(f"{self.port}: the plate driver plays {hello.min_setpoint_rate_hz}-"
                              f"{hello.max_setpoint_rate_hz} setpoints/s, not {self.rate_hz}")
        for name in ("full_scale_um_pp", "max_amplitude_um_pp"):
            value = getattr(hello, name)
            if not (math.isfinite(value) and value > 0):
                raise DeviceError(f"{self.port}: the plate driver reports {name} = {value:g}; it must be a "
                                  "positive number of µm p-p")
        return hello

    def _bind(self, hello: p.HelloReply) -> None:
        """The device's limits bind: the smaller limit and drive ceiling, codes scaled by its full scale; the
        output stage's limiter enforces them. Narrowed at each handshake, never widened over a run."""
        profile = self.profile
        device_limit = hello.max_amplitude_um_pp
        device_drive = getattr(hello, "max_drive_um_pp", None)  # v2 declares none: no overdrive (protocol.py)
        if device_drive is None:
            device_drive = max(device_limit, profile.max_drive_um_pp)
        limit = min(self.limit_um_pp, device_limit)
        overdrive = profile.max_drive_um_pp > profile.max_amplitude_um_pp and device_drive > device_limit
        drive = min(self.max_drive_um_pp, device_drive, hello.full_scale_um_pp) if overdrive else limit
        self.limit_um_pp, self.max_drive_um_pp = limit, max(limit, drive)
        self.full_scale_um_pp = hello.full_scale_um_pp
        # the largest code whose drive is not above the ceiling: rounding to nearest could add half a code
        self._top_fraction = min(1.0, math.floor(self.max_drive_um_pp / self.full_scale_um_pp * p.SETPOINT_SCALE)
                                 / p.SETPOINT_SCALE)
        self.device = hello
        stage = self._source
        if stage is not None and hasattr(stage, "limiter"):
            stage.limiter.bind(self.limit_um_pp, self.max_drive_um_pp)
        self._note_limits(hello, device_limit, device_drive)

    def _note_limits(self, hello: p.HelloReply, device_limit: float, device_drive: float) -> None:
        profile = self.profile
        notes = []
        if device_limit < profile.max_amplitude_um_pp:
            notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, below the profile's "
                         f"{profile.max_amplitude_um_pp:g}: using {self.limit_um_pp:g}")
        elif device_limit > profile.max_amplitude_um_pp:
            notes.append(f"the plate driver's limit is {device_limit:g} µm p-p, above the profile's "
                         f"{profile.max_amplitude_um_pp:g}: using the profile's {self.limit_um_pp:g}")
        if hello.full_scale_um_pp != profile.full_scale_um_pp:
            notes.append(f"the plate driver's full scale is {hello.full_scale_um_pp:g} µm p-p, not the profile's "
                         f"{profile.full_scale_um_pp:g}: setpoint codes are scaled to the driver's")
        if profile.max_drive_um_pp > profile.max_amplitude_um_pp and self.max_drive_um_pp < profile.max_drive_um_pp:
            if device_drive <= device_limit:
                why = ("speaks protocol v2, which declares no overdrive" if hello.version < 3
                       else "allows no overdrive")
                notes.append(f"the plate driver {why}: drive held at the limit, {self.max_drive_um_pp:g} µm p-p "
                             f"(the profile allows {profile.max_drive_um_pp:g})")
            else:
                notes.append(f"the plate driver allows drive up to {device_drive:g} µm p-p, below the profile's "
                             f"{profile.max_drive_um_pp:g}: using {self.max_drive_um_pp:g}")
        for note in notes:
            if note not in self.notes:
                self.notes.append(note)
