"""The plate-driver wire protocol, version 3 (and the layouts of version 2): framing, messages, codecs.

A frame is ``COBS(type u8 | seq u16 | payload | crc32 u32) 0x00``: COBS removes every zero
byte from the body, so 0x00 only ever ends a frame and a receiver resynchronises at the next one
after any garbage. The CRC-32 (IEEE 802.3, zlib's) covers type, seq and payload; all integers
and floats are little-endian. ``docs/protocol.md`` is the normative specification firmware authors
follow; the constants below are the ones it names (a test checks the two against each other).
Version 3 keeps version 2's framing and commands; HELLO_REPLY and TELEMETRY grew fields at their ends,
and SET_LOOP and SENSORS are new. The codecs read and write both versions' layouts: a HELLO_REPLY by its
version byte, a TELEMETRY by its length.

A 12 kHz stream is sent as one SETPOINTS frame of 12 values every 1 ms on a link with room for it
(921 600 baud), else of 24 values every 2 ms:

>>> batch_s_for(921600, 12000), batch_s_for(460800, 12000)
(0.001, 0.002)
>>> len(encode_frame(SETPOINTS, 1, setpoints_payload(0, 12000, np.zeros(12))))
43
>>> setpoint_codes(np.array([0.0, 0.5, 1.0, 1.2]))
array([    0, 32768, 65535, 65535], dtype=uint16)
"""


# The protocol in four modules by job, every public name re-exported here (callers import this one):
# protocol_spec (numbers and codes), protocol_frames (framing, CRC, the stream decoder),
# protocol_commands (host → device payloads), protocol_reports (device → host replies and reports).
from ultraglide.devices.protocol.commands import *  # noqa: F403
from ultraglide.devices.protocol.frames import *  # noqa: F403
from ultraglide.devices.protocol.reports import *  # noqa: F403
from ultraglide.devices.protocol.spec import *  # noqa: F403
