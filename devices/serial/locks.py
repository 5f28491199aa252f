"""Every lock of the serial plate driver, in one place, with the order they may be taken in.

The driver runs three threads: the caller's (start, stop, commands, status), the writer (:mod:`.streamer`) and
pyserial's reader (:mod:`.transport`, handing frames to :mod:`.telemetry`). Their shared state is guarded by
these locks, and by nothing else:

1. ``write`` (:class:`threading.Lock`): one frame on the port at a time, and the seq and stream index it takes.
   Held for one ``write``; inside it, ``replies`` may be taken to register a seq whose answer will be awaited
   (so an answer can never arrive before it is expected).
2. ``replies`` (:class:`threading.Condition`): the seqs awaited and their answers (ACK, NAK), the HELLO_REPLY.
   Taken inside ``write`` or alone; never takes another lock.
3. ``telemetry`` (:class:`threading.Condition`): the last TELEMETRY frame and how many arrived. A leaf.
4. ``account``, ``trim`` and ``drive`` (:class:`threading.Lock`): the run's record, the lead's correction and the
   drive tally. Leaves, held only for a copy or an addition: the writer takes them on the real-time path.

No lock is held while waiting for the device except a condition's own, released by its wait.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field


@dataclass(frozen=True)
class DriverLocks:
    """The driver's locks (see the module's docstring for what each guards and their order)."""

    write: threading.Lock = field(default_factory=threading.Lock)
    replies: threading.Condition = field(default_factory=threading.Condition)
    telemetry: threading.Condition = field(default_factory=threading.Condition)
    account: threading.Lock = field(default_factory=threading.Lock)
    trim: threading.Lock = field(default_factory=threading.Lock)
    drive: threading.Lock = field(default_factory=threading.Lock)
