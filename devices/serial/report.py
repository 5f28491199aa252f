"""What the plate driver tells of a run: its report in words with the exit status it earns, and its
status."""

from __future__ import annotations

from ultraglide.devices import protocol as p
from ultraglide.devices.serial.link import CUT_WORDS
from ultraglide.devices.serial.run_report import Incident, RunReport, seconds, times


class RunReporting:
    """What a run's report and status say: a part of :class:`~ultraglide.devices.serial.plate.SerialPlate`."""

    def report(self) -> RunReport:
        """The run so far in words, with the exit status it earns (see :mod:`ultraglide.devices.serial.run_report`)."""
        with self._account_lock:
            outages = [(o.lost_s, o.cause, o.back_s, o.not_sent, o.last_error, o.discarded_before)
                       for o in self._outages]
            refusals = {key: tuple(value) for key, value in self._refusals.items()}
            first = dict(self._fault_first_s)
            cut_at, stall, bad = self._cut_at, self._stall_longest, list(self._bad_received)
            late = self._late_longest
            writer_failure, dropped = self._writer_failure, self._outages_dropped
        incidents = []
        for lost_s, cause, back_s, not_sent, last_error, before in outages:
            if back_s is None:
                not_sent = self.counters.setpoints_discarded - before
                last = f" (the last try: {last_error})" if last_error else ""
                words = (f"plate lost at {seconds(lost_s)}: {cause}; not back by the end{last}; "
                         f"{not_sent} setpoints not sent")
            else:
                words = (f"plate lost at {seconds(lost_s)}: {cause}; back at {seconds(back_s)}; "
                         f"{not_sent} setpoints not sent")
            incidents.append(Incident(lost_s, "lost", words))
        if dropped:
            incidents.append(Incident(outages[-1][0], "lost", f"and {dropped} more losses of the plate"))
        if writer_failure is not None:
            incidents.append(Incident(writer_failure[0], "lost", f"the stream to the plate stopped at "
                                      f"{seconds(writer_failure[0])}: {writer_failure[1]}"))
        if cut_at is not None:
            incidents.append(Incident(cut_at[0], "cut", f"the plate cut its output at {seconds(cut_at[0])} "
                                      f"({CUT_WORDS.get(cut_at[1], cut_at[1])}): streaming stopped there; the host "
                                      "does not enable it again, so it stays off until the next run"))
        faults = self.fault_counts()
        severity = {"watchdog": "faulted", "over-limit": "faulted", "bad-command": "faulted", "trip": "cut",
                    "overheat": "cut"}
        for name, count in faults.items():
            if not count or cut_at is not None and name == cut_at[1] and count == 1:
                continue  # (the cut says it)
            kind = severity.get(name, "note")
            at = first.get(name, 0.0)
            incidents.append(Incident(at, kind, f"the plate raised {name} {times(count)} (first at {seconds(at)}): "
                                                f"{p.FAULT_WORDS.get(name, name)}"))
        for (command, reason), (count, at) in refusals.items():
            incidents.append(Incident(at, "faulted", f"the plate refused {times(count, 'frame')} of {command} "
                                                     f"({reason}), first at {seconds(at)}"
                                      + ("; its latched faults were not cleared again" if command == "CLEAR_FAULTS"
                                         else "")))
        if bad[0] or bad[1]:
            incidents.append(Incident(bad[2] or 0.0, "note", f"{times(bad[0] + bad[1], 'frame')} from the plate "
                                      f"arrived damaged ({bad[0]} with a bad CRC, {bad[1]} truncated or malformed), "
                                      f"first at {seconds(bad[2] or 0.0)}"))
        if stall[0]:
            skipped = self.counters.setpoints_skipped
            incidents.append(Incident(stall[1], "note", f"the host stalled {times(self.counters.host_stalls)} "
                                      f"(longest {stall[0]:.2f} s at {seconds(stall[1])})"
                                      + (f"; {skipped} setpoints skipped so the latency stays at the plate's "
                                         f"{1000 * self.lead / self.rate_hz:.0f} ms buffer" if skipped else "")))
        if late[0]:
            lasts_ms = 1000 * self.buffer_lasts_s
            incidents.append(Incident(late[1], "note", f"the host sent {times(self.counters.late_frames, 'frame')} "
                                      f"later than the plate's {lasts_ms:.0f} ms buffer lasts (the longest gap "
                                      f"{1000 * late[0]:.0f} ms, at {seconds(late[1])}): the plate may have run dry"))
        if self.counters.reenables:
            incidents.append(Incident(self._reenabled_first_s, "note",
                                      f"the plate was off while the host streamed to it "
                                      f"{times(self.counters.reenables)} (an ENABLE lost on the link?), first at "
                                      f"{seconds(self._reenabled_first_s)}: enabled again"))
        summary = self._link_summary()
        if self.counters.depth_corrections:
            worst_ms = 1000 * self._depth_worst / self.rate_hz
            summary.append(f"the plate's buffer drifted from its depth {times(self.counters.depth_corrections)} (by "
                           f"up to {worst_ms:.0f} ms: its clock against the host's, or its playback started again "
                           "late); the host moved its lead to bring it back")
        if self._rest_failure and self._rested:
            summary.append(f"the plate could not be rested at the end ({self._rest_failure}): its watchdog rests "
                           "it if it is still powered and was enabled")
        return RunReport.of(incidents, summary)

    def _link_summary(self) -> list[str]:
        run = self._link_run
        lines = []
        damaged = run["crc_errors"] + run["framing_errors"]
        if damaged:
            lines.append(f"the plate received {times(damaged, 'damaged frame')} ({run['crc_errors']} with a bad CRC, "
                         f"{run['framing_errors']} malformed)")
        lost, late, overrun = run["lost_setpoints"], run["late_setpoints"], run["overrun_setpoints"]
        if lost or late or overrun:
            parts = [f"{lost} lost" + (f" ({self.counters.setpoints_skipped} of them skipped by the host)"
                                       if self.counters.setpoints_skipped else "")]
            parts += [f"{late} late"] if late else []
            parts += [f"{overrun} dropped by overruns"] if overrun else []
            lines.append("the plate counted setpoints " + ", ".join(parts))
        return lines

    def status(self) -> dict:
        c = self.counters
        t = self.telemetry
        faults = self.fault_counts()
        report = self.report()
        return {
            "device": f"serial:{self.port}", "connected": self._connected.is_set(),
            "frames_sent": c.frames_sent, "setpoints_sent": c.setpoints_sent, "disconnects": c.disconnects,
            "reconnects": c.reconnects, "silences": c.silences, "bad_frames_received": c.bad_frames,
            "naks_received": c.naks, "send_stalls": c.send_stalls, "host_stalls": c.host_stalls,
            "late_frames": c.late_frames, "depth_corrections": c.depth_corrections,
            "setpoints_not_sent": c.setpoints_discarded, "setpoints_skipped": c.setpoints_skipped,
            "carrier_hz": round(self.carrier_hz, 2), "carrier_changes": c.carrier_changes,
            "output": "cut by the device" if self._cut else ("streaming" if self._output_on else "idle (disabled)"),
            "idle_rests": c.idle_rests, "reenables": c.reenables,
            "protocol_version": None if self.device is None else self.device.version,
            "device_name": None if self.device is None else self.device.name,
            "limit_um_pp": self.limit_um_pp, "max_drive_um_pp": self.max_drive_um_pp,
            "device_full_scale_um_pp": self.full_scale_um_pp, "notes": list(self.notes),
            "measured_um_pp": None if t is None else t.measured_um_pp,
            "device_frames_ok": None if t is None else t.frames_ok,
            "device_crc_errors": None if t is None else t.crc_errors,
            "device_lost_setpoints": None if t is None else t.lost_setpoints,
            "device_late_setpoints": None if t is None else t.late_setpoints,
            "faults": faults,
            "device_faults": [name for name, count in faults.items() if count],
            "report": report.as_dict(),
            **({"tracking": self.tracker.summary()} if self.tracker is not None else {}),
        }
