"""Shared test helpers."""

import fcntl
import functools
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# Property tests check behaviour, never speed: no per-example deadline, which a loaded machine would miss.
settings.register_profile("ultraglide", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ultraglide")

ROOT = Path(__file__).resolve().parent.parent


def wait_for(condition, timeout: float = 30.0) -> bool:
    """Wait on a condition (polled every 10 ms) with a deadline generous enough for a loaded machine;
    True once it holds, False at the deadline. Tests wait on what they need, never on a fixed sleep."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return False


def serve_plate(profile, **options):
    """A simulated plate on a pseudo-terminal (``PtyPlate(profile, **options)``, started), its threads in real time
    where the machine allows, as a command's simulated plate's and the engine's are: at ordinary priority beside
    CPU hogs, a plate's output thread preempted for tens of milliseconds ran its buffer dry with the host on time,
    or held the interpreter's lock while the host's threads waited on it."""
    from ultraglide.devices.sim.pty_plate import PtyPlate
    from ultraglide.render.engine.realtime import threads_started_in_real_time

    with threads_started_in_real_time():
        return PtyPlate(profile, **options).start()


_SERVER = None


def _cli_server():
    """This worker's command server (tests/cli_server.py), started at first use; None when turned off
    (``ULTRAGLIDE_TEST_FORK=0`` runs every command as a plain subprocess)."""
    global _SERVER
    if os.environ.get("ULTRAGLIDE_TEST_FORK", "1") == "0":
        return None
    if _SERVER is None:
        import atexit

        from cli_server import CliServer

        _SERVER = CliServer()
        atexit.register(_SERVER.close)
    return _SERVER


def _file_size_limit(limit_bytes):
    def apply():
        import resource
        import signal

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return apply


def run_cli(*args, check=False, env=None, inherit_env=True, timeout=300, file_size_limit=None, **kwargs):
    """Run the ``ultraglide`` command as a user would, in a new process: ``python -m ultraglide ARGS``
    forked from a process that has numpy, scipy and numba imported (tests/cli_server.py), or a plain
    subprocess when the environment asks for one. ``env``: added to this process's environment, or with
    ``inherit_env=False`` the whole of it. ``file_size_limit`` (bytes): no file of the command's may
    grow past it (RLIMIT_FSIZE: the kernel refuses with EFBIG, as a full disk does with ENOSPC)."""
    merged = {**os.environ, **(env or {})} if inherit_env else dict(env or {})
    args = [str(arg) for arg in args]
    server = _cli_server()
    if server is not None and server.serves(merged):
        result = server.run(args, merged, Path(kwargs.get("cwd", ROOT)), timeout, file_size_limit)
    else:
        result = subprocess.run([sys.executable, "-m", "ultraglide", *args], capture_output=True,
                                text=True, env=merged, timeout=timeout, cwd=kwargs.get("cwd", ROOT),
                                preexec_fn=None if file_size_limit is None else _file_size_limit(file_size_limit))
    if check and result.returncode != 0:
        raise AssertionError(f"ultraglide {' '.join(map(str, args))} failed:\n{result.stderr}")
    return result


def start_cli(*args, stdout=None, stderr=None, env=None, cwd=ROOT, text=True):
    """Start the ``ultraglide`` command as ``run_cli`` runs it, and return it running (``pid``, ``poll``,
    ``wait``, ``send_signal``, ``kill``; ``stdout`` and ``stderr`` where asked for with ``subprocess.PIPE``,
    as ``subprocess.Popen``'s): for a test that signals the command's own process, kills it, or reads its
    output while it runs. ``stdout`` and ``stderr``: a file, ``subprocess.PIPE``, ``subprocess.DEVNULL`` or
    None (this process's own)."""
    merged = {**os.environ, **(env or {})}
    args = [str(arg) for arg in args]
    server = _cli_server()
    if server is None or not server.serves(merged):
        return subprocess.Popen([sys.executable, "-m", "ultraglide", *args], stdin=subprocess.DEVNULL, stdout=stdout,
                                stderr=stderr, env=merged, cwd=cwd, text=text)
    given, made, pipes = [], [], {}
    for name, target, own in (("stdout", stdout, 1), ("stderr", stderr, 2)):
        if target == subprocess.PIPE:
            read, write = os.pipe()
            pipes[name] = open(read, "r" if text else "rb")  # noqa: SIM115 - the caller's, as Popen's
            made.append(write)
            given.append(write)
        elif target == subprocess.DEVNULL:
            made.append(os.open(os.devnull, os.O_WRONLY))
            given.append(made[-1])
        else:
            given.append(own if target is None else target.fileno())
    try:
        process = server.start(args, merged, Path(cwd), *given)
    finally:
        for fd in made:
            os.close(fd)
    process.stdout, process.stderr = pipes.get("stdout"), pipes.get("stderr")
    return process


def assert_one_line_error(result):
    """A user error: non-zero exit, one line on stderr, no traceback."""
    assert result.returncode != 0, result.stdout
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr
    return lines[0]


def may_run_in_real_time() -> bool:
    """Whether this process may put a thread at SCHED_FIFO (root, CAP_SYS_NICE or RLIMIT_RTPRIO), asked on a
    thread of its own that gives it back."""
    import threading

    allowed = []

    def ask():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except OSError:
            allowed.append(False)
            return
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        allowed.append(True)

    thread = threading.Thread(target=ask)
    thread.start()
    thread.join()
    return allowed[0]


def thread_scheduling(pid: int) -> dict[int, tuple[int, int]]:
    """Each thread of process ``pid``: its scheduling policy and real-time priority."""
    found = {}
    for tid in map(int, os.listdir(f"/proc/{pid}/task")):
        try:
            found[tid] = (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority)
        except ProcessLookupError:  # a thread that ended meanwhile
            continue
    return found


@pytest.fixture
def tap():
    """The simulated plate on a real pty, every frame it decodes kept (tests/plate_tap.py); stopped after."""
    from plate_tap import PlateTap

    served = PlateTap()
    yield served
    served.close()


@pytest.fixture
def cli():
    return run_cli


def source_copy(destination: Path) -> Path:
    """The working tree as a fresh clone has it: no virtual environment, builds, caches or artifacts."""
    import shutil

    skip = shutil.ignore_patterns(".git", ".venv", "build", "dist", "artifacts", "__pycache__", "*.egg-info",
                                  ".pytest_cache", ".ruff_cache", ".hypothesis", "site", "*.so")
    shutil.copytree(ROOT, destination, ignore=skip)
    return destination


# ---- slow tests ---------------------------------------------------------------------------------------
# `-m "not slow"` is the quick loop. A test is slow when it says so (@pytest.mark.slow) or when it, a
# module-level helper (function or class) it calls, or a fixture it uses starts a process (the command, a
# server, Xvfb, the engine's own process, which the demo starts too): those take seconds each, more on a
# loaded machine. Marked here from the source, so new test files need no bookkeeping.
SLOW_WORDS = ("run_cli", "start_cli", "subprocess.", "Popen", "XvfbDemo", "cli(", "Engine.start(", "DemoApp(")


@functools.cache
def _source(function) -> str | None:
    """A function's or class's source, read once: parametrised tests and shared helpers ask many times, and
    inspect parses a class's whole module each time (it was 40 % of collecting the suite)."""
    import inspect

    try:
        return inspect.getsource(function)
    except (OSError, TypeError):
        return None


def _starts_processes(function, module, seen=None) -> bool:
    import inspect

    seen = seen if seen is not None else set()
    if function in seen:
        return False
    seen.add(function)
    source = _source(function)
    if source is None:
        return False
    if any(word in source for word in SLOW_WORDS):
        return True
    helpers = [getattr(module, name) for name in vars(module) if name in source and name != function.__name__]
    return any((inspect.isfunction(h) or inspect.isclass(h)) and h.__module__ == module.__name__
               and _starts_processes(h, module, seen) for h in helpers)


@functools.cache
def _test_starts_processes(function, module) -> bool:
    return _starts_processes(function, module)  # once a test function, however many parameters it has


def _fixtures_start_processes(item) -> bool:
    """Whether a fixture the test uses (or one those use) starts a process; pytest's own fixtures do not."""
    import inspect

    info = getattr(item, "_fixtureinfo", None)
    for definitions in (info.name2fixturedefs.values() if info is not None else ()):
        for definition in definitions:
            function = inspect.unwrap(definition.func)
            module = inspect.getmodule(function)
            if module is not None and Path(module.__file__ or "").parent == Path(__file__).parent \
                    and _starts_processes(function, module):
                return True
    return False


# files whose tests take the longest (tens of seconds each, measured with --durations): they start first, so that
# no worker is left running them alone while the others are done (the tour at the end of the alphabet left one
# worker busy for the last 200 s of a 22 min run)
LONGEST_FIRST = ("test_readme_tour.py", "test_packaging.py", "test_experiment_sessions.py", "test_friction_loop.py",
                 "test_calibration_on_plate.py", "test_figures_print.py", "test_tracking.py", "test_cli_model.py")


def pytest_collection_modifyitems(config, items):
    for item in items:
        function = getattr(item, "function", None)
        if function is None or item.get_closest_marker("slow"):
            continue
        if "cli" in getattr(item, "fixturenames", ()) or _test_starts_processes(function, item.module) \
                or _fixtures_start_processes(item):
            item.add_marker(pytest.mark.slow)

    def start(item) -> tuple[int, int]:
        if not item.get_closest_marker("slow"):
            return 2, 0
        name = item.path.name
        return (0, LONGEST_FIRST.index(name)) if name in LONGEST_FIRST else (1, 0)
    items.sort(key=start)  # stable: each file's tests keep their order


QEMU_LOCK = os.path.join(tempfile.gettempdir(), "ultraglide-qemu-tests.lock")


@pytest.fixture
def one_qemu():
    """One QEMU at a time across the test workers: each streams in real time on a two-core machine."""
    with open(QEMU_LOCK, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield
