"""``ultraglide serve``: the real-time engine on a device, driven by other programs over a local WebSocket.

The engine starts as ``play``'s does (its own process, the plate behind its limiter); the service
(:mod:`apps.service.server`) then listens, and prints its address as the first line on standard output. Stopped by
Ctrl-C or SIGTERM, the engine ramps the plate to rest before the command ends. See ``docs/service.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import stat
import sys
import time

from ultraglide.apps.cli.options import MODEL_HELP, output_option
from ultraglide.apps.cli.signals import held, stop_requested
from ultraglide.apps.cli.types import FORCE_N, Bounded
from ultraglide.apps.commands.plate_choice import add_plate_options, plate_of
from ultraglide.render.physics.default_model import DEFAULT_MODEL

PORT = Bounded(0, 65535, whole=True)
VIEW_MM = Bounded(1.0, 2000.0, "mm")
DEFAULT_PORT = 8765


def add_parser(commands: argparse._SubParsersAction) -> None:
    """``ultraglide serve``: its options."""
    serve = commands.add_parser(
        "serve", help="run the engine on a device for other programs: a local WebSocket service",
        description="Run the real-time engine on a device and listen on a local WebSocket: clients (Python's "
                    "ultraglide.client, the page with --page, any program speaking the protocol of "
                    "docs/service.md) place textures as sprites in views and send touches; the engine renders the "
                    "sprite under the finger. The first line printed is the service's address.")
    serve.add_argument("textures", nargs="*", metavar="TEXTURE",
                       help="textures (files, images or library names) placed as sprites filling the view at start, "
                            "side by side")
    output_option(serve, "--device", kind="device", metavar="URL",
                  help="sim, serial:PORT[?baud=N], audio[:NAME_OR_INDEX][?rate=N], wav:PATH or null (default: the "
                       "rig's device, else sim); audio and serial need --rig or --profile")
    add_plate_options(serve, serve, device_default="sim")
    serve.add_argument("--model", default=DEFAULT_MODEL, metavar="MODEL",
                       help=f"{MODEL_HELP} (default: {DEFAULT_MODEL})")
    serve.add_argument("--force", type=FORCE_N, metavar="N",
                       help="the finger's force when a touch gives no pressure or force, N (default: 0.5)")
    serve.add_argument("--closed-loop", action="store_true",
                       help="make the friction the plate's force sensors measure follow the texture (a plate driver "
                            "with force sensors; on sim, a simulated finger)")
    serve.add_argument("--host", default="127.0.0.1",
                       help="the address to listen on (default: 127.0.0.1, loopback; any other address asks clients "
                            "for the token printed at start)")
    serve.add_argument("--port", type=PORT, default=DEFAULT_PORT,
                       help=f"the TCP port (default: {DEFAULT_PORT}; 0: a free one, printed)")
    serve.add_argument("--unix", metavar="PATH", help="listen on a Unix socket at PATH instead of TCP")
    serve.add_argument("--page", action="store_true",
                       help="also serve the page (http://HOST:PORT/): pointer events in a browser drive the engine")
    serve.add_argument("--view-mm", type=VIEW_MM, nargs=2, default=[160.0, 100.0], metavar=("WIDTH", "HEIGHT"),
                       help="the default view's size until a client sets it, mm (default: 160 100)")
    serve.add_argument("--touch-panel", metavar="PATH",
                       help="the engine reads this touch panel itself: its Linux evdev node (/dev/input/eventN, "
                            "readable by the input group; evtest lists them) or a FIFO carrying evdev records; mapped "
                            "onto the view by the rig's [touch]; clients then only place sprites (their touches are "
                            "refused)")
    serve.add_argument("--touch-range", action="append", default=[], metavar="AXIS=MIN:MAX",
                       help="an axis range of the touch panel in its own units, AXIS x, y or pressure (evtest prints "
                            "them): needed for a FIFO, which cannot say them; overrides the rig's and the kernel's; "
                            "repeat for each axis")
    output_option(serve, "--envelope-csv", kind="log", metavar="FILE.csv",
                  help="record the envelope as it plays, as play does: t_s, x_mm, y_mm (on the view), down, "
                       "target_ratio, target_um_pp, commanded_um_pp")
    serve.add_argument("--json", action="store_true",
                       help="the first line as JSON (url, page, token) and the final status as JSON")
    serve.set_defaults(run=run)


def run(args) -> int:
    from pathlib import Path

    from ultraglide.apps.cli.errors import UsageError
    from ultraglide.apps.service.server import Service, needs_token, new_token
    from ultraglide.devices.urls import parse_device_url
    from ultraglide.render.engine import Engine, EngineConfig
    from ultraglide.render.physics.calibration import load_model

    parse_device_url(args.device)
    if args.unix and (args.host != "127.0.0.1" or args.port != DEFAULT_PORT or args.page):
        raise UsageError("--unix listens on a Unix socket: leave out --host, --port and --page")
    if args.unix and os.path.lexists(args.unix):
        raise UsageError(f"--unix {args.unix}: something is there already; remove it or choose another path")
    if args.unix and not Path(args.unix).parent.is_dir():
        raise UsageError(f"--unix {args.unix}: no directory {Path(args.unix).parent}")
    if args.envelope_csv and not Path(args.envelope_csv).parent.is_dir():
        raise UsageError(f"{args.envelope_csv}: no directory {Path(args.envelope_csv).parent} to write it in")
    profile = plate_of(args)
    load_model(args.model)  # a bad model is one line before the engine starts
    token = new_token() if args.unix is None and needs_token(args.host) else None
    rig = getattr(args, "loaded_rig", None)
    touch = rig.touch if rig is not None else None
    drives = touch.drives if touch is not None else "first"
    scale = {} if touch is None or touch.pressure_full_scale_n is None else \
        {"pressure_full_scale_n": touch.pressure_full_scale_n}  # the panel's pressure scale for clients' touches too
    service = Service(None, profile, token=token, page=args.page, view_mm=tuple(args.view_mm), drives=drives,
                      **scale)
    service.place_startup_textures(args.textures)
    panel = _open_panel(args, rig)
    if panel is not None:
        service.touch_panel = panel.path  # clients' touches refused from the first connection on
    config = EngineConfig(texture=service.first_texture(), model=args.model, profile=args.profile,
                          device=args.device, default_force_n=0.5 if args.force is None else args.force,
                          closed_loop=args.closed_loop, envelope_csv=args.envelope_csv)
    try:
        engine = Engine.start(config)
    except BaseException:
        if panel is not None:
            panel.close()
        raise
    service.engine = engine
    failure = stopped = feed = None
    started = time.perf_counter()
    try:
        engine.wait_ready()
        started = time.perf_counter()  # the loss's time is said from here
        if panel is not None:
            from ultraglide.apps.service.panel import PanelFeed

            feed = PanelFeed(service, panel, rig.touch if rig is not None else None)
        try:
            failure = _serve(service, args, feed)
        except KeyboardInterrupt as interrupt:  # Ctrl-C, SIGTERM: the way a service is stopped; reported below
            stopped = interrupt
    finally:
        with held():  # a stop signal arriving now waits until the plate is at rest
            if panel is not None:
                panel.close()
            service.worker.shutdown(wait=True, cancel_futures=True)
            final = engine.stop()
            if args.unix:
                _remove_socket(args.unix)
    status = _report(final, service, args, failure, feed, engine.loss, started)
    if stopped is not None:
        raise stopped  # the command's status says it was stopped (130, 143)
    return status


def _open_panel(args, rig):
    """The touch panel's reader (``--touch-panel``), opened and its axis ranges known, or None; a mistake is one line
    (exit 2) before the engine starts."""
    from ultraglide.devices.touch.evdev import PanelReader, TouchPanelUsageError, given_ranges

    if args.touch_panel is None:
        if args.touch_range:
            raise TouchPanelUsageError("--touch-range gives a touch panel's axis ranges: add --touch-panel PATH")
        return None
    touch = rig.touch if rig is not None else None
    ranges = given_ranges(args.touch_range, touch.axis_ranges if touch is not None else None)
    return PanelReader(args.touch_panel, ranges)


def _serve(service, args, feed=None) -> str | None:
    """Listen until a stop signal or the engine's end.

    The loop runs inside :func:`held`: a stop signal is noted, and the loop, which looks for it every
    ``POLL_S``, closes its connections and ends; the signal is then raised here, as the block ends. Raised
    wherever it found the loop's thread, it once landed in websockets' reading of a message and the loop's
    shutdown printed a traceback ("aclose(): asynchronous generator is already running")."""
    import asyncio
    import threading

    from ultraglide.apps.service.protocol import MAX_MESSAGE_BYTES
    from ultraglide.apps.service.server import ServiceError, short_path_connection
    from websockets.asyncio.server import serve, unix_serve

    async def main() -> str | None:
        options = {"max_size": MAX_MESSAGE_BYTES, "max_queue": 64, "write_limit": 256 * 1024,
                   "ping_interval": 5.0, "ping_timeout": 10.0, "compression": None,
                   "create_connection": short_path_connection()}
        try:
            if args.unix:
                server = await unix_serve(service.handle, args.unix, **options)
            else:
                server = await serve(service.handle, args.host, args.port, process_request=service.process_request,
                                     origins=service.origins, **options)
        except OSError as error:
            where = args.unix or f"{args.host}:{args.port}"
            raise ServiceError(f"cannot listen on {where}: {error.strerror or error}") from None
        async with _closing(server):
            if args.unix:
                urls = {"url": f"ws+unix:{args.unix}", "page": None, "token": None}
            else:
                port = server.sockets[0].getsockname()[1]
                host = f"[{args.host}]" if ":" in args.host else args.host
                query = f"?token={service.token}" if service.token else ""
                urls = {"url": f"ws://{host}:{port}/ws{query}",
                        "page": f"http://{host}:{port}/{query}" if args.page else None, "token": service.token}
                origins = [None]
                if args.page:
                    origins.append(f"http://{host}:{port}")
                    if args.host == "127.0.0.1":
                        origins.append(f"http://localhost:{port}")
                service.origins[:] = origins  # the list serve() checks each handshake against
            if feed is not None:
                urls["touch_panel"] = {"path": feed.reader.path, "kind": feed.reader.kind,
                                       "ranges": feed.reader.ranges.words()}
            if args.json:
                print(json.dumps(urls), flush=True)
            else:
                print(" ".join(v for v in (urls["url"], urls["page"]) if v), flush=True)
                if service.token:
                    print(f"token: {service.token} (clients give it as ?token=...)", flush=True)
                print(f"serving {service.engine.config.device} ({service.profile.name}, limit "
                      f"{service.profile.max_amplitude_um_pp:g} µm p-p); Ctrl-C stops, the plate at rest",
                      flush=True)
                if feed is not None:
                    print(f"{feed.reader.words()}; clients' touches are refused", flush=True)
            service.priority = _loop_in_real_time(service)
            if feed is not None:
                feed.start(asyncio.get_running_loop())
            stop = threading.Event()
            publisher = threading.Thread(target=service.publish, args=(asyncio.get_running_loop(), stop),
                                         name="ultraglide-publisher", daemon=True)
            publisher.start()
            try:
                while service.engine.alive and service.engine.loss is None:
                    if feed is not None and feed.gone:
                        return feed.gone
                    if stop_requested():
                        return None
                    await asyncio.sleep(POLL_S)
                # its process ended: the supervisor makes the device safe and says how (the run's report)
                if service.engine.supervisor.wait(LOSS_SAID_S):
                    return None
                return "the engine ended unexpectedly"
            finally:
                if feed is not None:
                    feed.stop()
                stop.set()
                for session in list(service.sessions):
                    service._leave(session)

    with held():
        return run_loop_bounded(main())


POLL_S = 0.05  # how often the service looks at its engine, its touch panel and for a stop signal
CLOSE_S = 2.0  # what the service's connections get to close once it stops; then they are cancelled
LOSS_SAID_S = 5.0  # the longest wait, once the engine's process has ended, for its supervisor to have made it safe
SHUTDOWN_S = 10.0  # what the loop's tasks get to end once stopped; then the loop is closed whatever is left


def _closing(server):
    """``async with server``, but its connections get :data:`CLOSE_S` to close: websockets waits for every
    connection's handler without a bound, and a client that read nothing once held a stopped service for good (its
    loop then cancels what is left, :func:`run_loop_bounded`)."""
    import asyncio
    import contextlib

    @contextlib.asynccontextmanager
    async def closing():
        try:
            yield server
        finally:
            server.close()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(server.wait_closed(), CLOSE_S)

    return closing()


def run_loop_bounded(coroutine):
    """``asyncio.run(coroutine)``, but a stop (the coroutine's end, or a KeyboardInterrupt raised through the loop
    where no :func:`held` block holds it back) gives the loop's tasks :data:`SHUTDOWN_S` to end after they are
    cancelled, where ``asyncio.run`` waits for them for ever: a service stopped with a client connected once did
    not end within 60 s, its main thread in ``asyncio.run``'s cancellation of the tasks left (a connection's task
    that never finished). The plate is brought to rest after this returns or raises, by the command."""
    import asyncio
    import contextlib

    loop = asyncio.new_event_loop()
    try:
        asyncio.set_event_loop(loop)
        task = loop.create_task(coroutine)
        try:
            return loop.run_until_complete(task)
        finally:
            pending = [t for t in asyncio.all_tasks(loop) if not t.done()]
            for left in pending:
                left.cancel()
            if pending:
                with contextlib.suppress(BaseException):
                    loop.run_until_complete(asyncio.wait(pending, timeout=SHUTDOWN_S))
            with contextlib.suppress(BaseException):
                loop.run_until_complete(asyncio.wait_for(loop.shutdown_asyncgens(), SHUTDOWN_S))
    finally:
        asyncio.set_event_loop(None)
        loop.close()


LOOP_SLICE_S = 0.0001  # the loop thread's time slice (Linux 6.12+'s EEVDF, for ordinary threads; 0.1 ms its least)


def _loop_in_real_time(service, slice_s: float = LOOP_SLICE_S) -> str:
    """The loop's thread (this one: touches, lifts) at nice -10 where the OS allows, with a short time slice: at
    ordinary priority on a busy machine it went unscheduled for 60-80 ms, and a client that died with its finger down
    was noticed that late. Not SCHED_FIFO, as the engine's threads are: a flood of messages would then keep the
    engine's and a simulated plate's threads of equal priority off the CPU (a test saw the engine's clock jump 170
    ms). The worker (textures decoded, views composed) is started first and keeps the ordinary priority: it is heavy
    and not on the touch path; the threads started after (the publisher, a touch panel's reader) inherit both.

    The slice (``slice_s``, 0: the kernel's own, 1.4 ms here): Linux's scheduler (EEVDF, 6.12 and later) lets a
    thread that wakes preempt the one running only when its slice is the shorter; at the kernel's slice a touch that
    woke the loop waited for the ordinary program running on its CPU to finish its own. A shorter slice gives the loop
    no more CPU than its nice does, only sooner
    (:func:`~ultraglide.render.engine.realtime.short_time_slice`). Older kernels ignore it.

    Returns
    -------
    str
        The loop's scheduling in words: ``nice -10, a 0.1 ms slice``, ``nice -5`` ...
    """
    import os
    import threading

    service.worker.submit(int).result()  # its thread exists now, and keeps the ordinary priority
    words = "normal (no permission to raise it)"
    for nice in (-10, -5):
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)  # this thread only (Linux)
            words = f"nice {nice}"
            break
        except (OSError, AttributeError):
            continue
    from ultraglide.render.engine.realtime import short_time_slice

    if slice_s > 0 and short_time_slice(slice_s):
        words += f", a {slice_s * 1e3:g} ms slice"
    return words


def _remove_socket(path: str) -> None:
    """The Unix socket we made, and nothing else."""
    try:
        if stat.S_ISSOCK(os.lstat(path).st_mode):
            os.unlink(path)
    except OSError:
        pass


def _report(final, service, args, failure: str | None, feed=None, loss=None, started: float | None = None) -> int:
    """The run's summary (words, or JSON with ``--json``) and its exit status: a failure's 1, a lost engine's 7 (its
    words from the supervisor: what happened, when, what made the device safe), else the device's report's."""
    from ultraglide.apps.cli.output import print_json
    from ultraglide.apps.service.server import RATE_PER_S
    from ultraglide.devices.serial.run_report import RunReport

    figures = final.summary() if final is not None else {}
    device_status = figures.pop("device_status", {}) or {}
    report = RunReport.from_dict(device_status.get("report"))
    if loss is not None:  # the device's own report stops where its process did
        report = report.with_lines(loss.lines(started), loss.exit_status)
    summary = {"device": figures.get("device"), "blocks": figures.get("blocks"),
               "late_blocks": figures.get("late_blocks"), "underruns": figures.get("underruns"),
               "touches": service.touches, "touches_ignored": service.touches_ignored,
               "messages": service.messages_read, "rate_refused": service.rate_refusals,
               "faults": device_status.get("fault_counts") or {}, "limiter": device_status.get("limiter", ""),
               "paced_s": device_status.get("paced_s", 0.0), "error": failure,
               "engine_lost": None if loss is None else loss.lines(started)}
    if feed is not None:
        summary["touch_panel"] = feed.summary()
    if args.json:
        print_json(summary)
    elif final is not None:
        print(f"served on {final.device}: {final.blocks} blocks rendered, {final.late_blocks} late, "
              f"{final.underruns} device underruns; {service.touches} touches from "
              f"{'the touch panel' if feed is not None else 'clients'}")
        if service.rate_refusals:
            print(f"{service.rate_refusals} of {service.messages_read} messages refused: their client sent more "
                  f"than {RATE_PER_S:g} a second")
        from ultraglide.devices.sinks.audio import pacing_words  # not at import: it brings the output stage

        paced = pacing_words(device_status)
        if paced:
            print(paced)
        if summary["limiter"]:
            print(summary["limiter"])
        for line in report.lines:
            print(line)
    if failure:
        print(f"ultraglide serve: {failure}", file=sys.stderr)
        return 1
    if report.exit_status:
        print(f"ultraglide serve: {report.verdict}", file=sys.stderr)
    return report.exit_status
