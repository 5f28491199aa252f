"""The ``ultraglide`` command: parse, run the command, and turn what went wrong into one line and an exit status.

Errors of ours (:class:`ultraglide.UltraglideError`) and OSErrors are a person's to fix: one line, exit 2 for
input the command cannot use, 1 for the rest, or the error's own ``exit_status``: a lost engine's 7
(:func:`ultraglide.apps.cli.errors.exit_status`). A stop signal (Ctrl-C, SIGTERM, SIGHUP) stops a command through
every ``finally``: exit 128 + its number. Anything else is a bug and keeps its traceback.

The exit statuses (docs/guide/commands.md, Exit statuses):

=========  ======================================================================================================
 0         done, clean
 1         an error a person can fix (a device, an output that cannot be written, a resource that ran out),
           said in one line
 2         usage: options that make no sense (argparse's, and ours), or an input (a value, a file the command
           reads) it cannot use, said in one line
 3, 4, 5   a run on a plate: the plate faulted, was lost, cut its output (``devices.serial.run_report``)
 6         ``plate check``: the plate broke a rule of the protocol
 7         the engine was lost: its process died or froze mid-run; the device was made safe by the command
           (``render.engine.supervisor``)
 128 + N   stopped by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP)
=========  ======================================================================================================
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import os
import signal
import sys

from ultraglide.apps.cli import errors
from ultraglide.apps.cli.files import check_outputs
from ultraglide.apps.cli.output import PrintableStream, one_line
from ultraglide.apps.cli.parser import build_parser
from ultraglide.apps.cli.signals import StopSignals
from ultraglide.apps.commands.plate_choice import choose_plate
from ultraglide.devices.serial.run_report import EXIT_ENGINE_LOST

from ultraglide.atomic import release_checked
from ultraglide.errors import out_of_memory


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"ultraglide: warning: {one_line(str(message))}", file=file or sys.stderr)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return 0
    import warnings

    warnings.showwarning = _show_warning
    stop = StopSignals()  # SIGTERM and SIGHUP stop a command as Ctrl-C does, through every finally
    stop.install()
    streams = sys.stdout, sys.stderr  # text from files reaches the terminal escaped (apps.cli.output)
    sys.stdout, sys.stderr = PrintableStream(sys.stdout), PrintableStream(sys.stderr, keep="\n\t\r")
    try:
        try:  # which plate: --rig, --profile, or the simulated plate's own; a real output needs one named
            choose_plate(args)
        except errors.USER_ERRORS as error:
            print(f"ultraglide {args.command}: error: {one_line(errors.describe(error))}", file=sys.stderr)
            return 2
        check_outputs(args)  # what it would write, before any work: not a directory, not a missing folder ...
        status = int(args.run(args) or 0)
    except KeyboardInterrupt as interrupt:
        stop.restore()  # from here on the stop signals are ignored: the command has stopped
        return _stopped(stop.received or getattr(interrupt, "signum", signal.SIGINT))
    except BrokenPipeError:  # the reader left (``ultraglide textures | head``): stop quietly, as Unix tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at interpreter exit
        return 128 + signal.SIGPIPE
    except errors.USER_ERRORS as error:
        print(f"ultraglide {args.command}: error: {one_line(errors.describe(error))}", file=sys.stderr)
        return errors.exit_status(error)
    except ModuleNotFoundError as error:  # an optional dependency (the demo's, the figures') not installed
        message = errors.missing_extra(error)
        if message is None:
            raise
        print(f"ultraglide {args.command}: error: {message}", file=sys.stderr)
        return 2
    except Exception as error:  # memory refused, whatever a library raised for it (numpy's MemoryError, numba's)
        words = out_of_memory(error)
        if words is None:
            raise  # anything else is a bug: its traceback
        print(f"ultraglide {args.command}: error: {one_line(words)}", file=sys.stderr)
        return 1
    finally:
        release_checked()  # pipes held open since the check, which the command did not take
        stop.restore()
        sys.stdout, sys.stderr = streams
    return _stopped(stop.received) if stop.received is not None else status


def console() -> int:
    """The ``ultraglide`` command (and ``python -m ultraglide``): :func:`main`; an error no handler took (a bug) ends
    as Python ends, with its traceback."""
    status = main()
    # the finished command's objects need no cycle collection at exit, which otherwise walks every object numba,
    # scipy and the texture made: about 0.15 s of a short command's time
    gc.freeze()
    if status == EXIT_ENGINE_LOST:
        end_after_loss(status)
    return status


def end_after_loss(status: int) -> None:
    """End a command whose engine was lost now that its device is safe and its report said: the ``atexit``
    functions, the standard streams flushed, then ``os._exit``, without the interpreter's teardown.

    A lost engine's exit is timed (aims of 100 ms after a death, 250 ms after a freeze, issue 45), and the teardown
    of an interpreter with numpy, scipy and numba loaded (every module's objects freed, LLVM's and OpenBLAS's
    destructors) took 0.16-0.30 s of it on a loaded machine. Threads are not waited for: by the time a loss is
    reported the device was made safe and the command's files finished or removed (``render.engine.supervisor``),
    so what is left is idle (an executor's workers wait for work they will never get). Commands that end
    otherwise end as Python ends.

    Parameters
    ----------
    status : int
        The exit status (0-255), :data:`~ultraglide.devices.serial.run_report.EXIT_ENGINE_LOST`.

    Examples
    --------
    >>> end_after_loss(7)  # doctest: +SKIP
    """
    atexit._run_exitfuncs()  # multiprocessing's finalizers, the resource tracker's, coverage's
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # a reader gone (a closed pipe): nothing more to say to it
            stream.flush()
    os._exit(status & 0xFF)


def _stopped(signum: int) -> int:
    """One line and the shell's status for a command stopped by a signal: 130 for Ctrl-C, 143 for SIGTERM."""
    print(f"ultraglide: stopped ({signal.Signals(signum).name})", file=sys.stderr)
    return 128 + signum


if __name__ == "__main__":
    sys.exit(console())
