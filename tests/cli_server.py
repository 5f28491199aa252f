"""Run the ``ultraglide`` command in a fresh process without paying for its libraries' import each time.

Most of a short command's CPU time is importing numpy, scipy, numba and matplotlib (about 1 s of CPU against 0.1 s
for the work of ``export --duration-s 0.1``); the suite runs the command hundreds of times. A server process per
test worker imports those libraries once, builds numba's CPU target (which a process otherwise builds at its first
compiled function, cached or not), imports the modules of ours that rendering commands load (the command line, the
renderer, textures, the engine: 0.14 s of an ``export``'s 0.27 s) and loads our compiled kernels, then forks a child
for each command: the child takes the caller's environment, working directory, stdout and stderr pipes, runs
``python -m ultraglide ARGS`` through runpy exactly as the interpreter would, and leaves as the interpreter's
shutdown does (joined threads, atexit handlers, flushed streams; the exit status of ``sys.exit``, of an uncaught
exception or of Ctrl-C), so its exit status, output and files are the command's. It skips what the shutdown does
after that, the teardown of every module: in a forked child that writes to every page of the server's heap that a
preloaded object lives on (reference counts, copy-on-write), 0.15 s of CPU a command against 0.03-0.08 s for a short
command's own work (the real processes below keep the whole shutdown tested). The modules of ours preloaded read
nothing at import that a command's environment, directory or arguments could change (the server refuses to serve if
one loads a sound or window library, whose start reads the environment); every other module of ours is imported in
the child. The README's tour (its commands that run beside the test), the packaging test and the tests that run
``python -m ultraglide`` start real processes.

The server is single-threaded (a fork beside running threads can inherit a held lock): SIGCHLD wakes
its loop, which reaps the children and reports each exit status on the request's own socket.
A caller whose environment differs from the server's in a variable the preloaded libraries read at
import (NUMBA_*, OMP_*, OPENBLAS_*, MKL_*, PYTHON*) gets a plain subprocess instead.
"""

from __future__ import annotations

import json
import os
import select
import selectors
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

PRELOAD = ("numpy", "scipy.ndimage", "scipy.interpolate", "numba", "soundfile",
           # the figures' (0.7 s of CPU for each command that draws one); every figure of ours is drawn with Agg
           "matplotlib.pyplot", "matplotlib.backends.backend_agg", "matplotlib.backends.backend_pdf",
           "fontTools.subset")
# ours, loaded once: the command line and what export and play import (none reads the environment at import)
PRELOAD_OURS = ("ultraglide.apps.cli.main", "ultraglide.apps.commands.export", "ultraglide.apps.commands.play",
                "ultraglide.apps.commands.output_report", "ultraglide.apps.commands.render_setup",
                "ultraglide.render.engine", "ultraglide.render.engine.sources", "ultraglide.api")
NOT_PRELOADED = ("sounddevice", "pygame", "serial")  # started with the server's environment, they would keep it
# our compiled kernels, loaded from numba's cache (or compiled) once here rather than in every rendering command
# (31 ms of CPU of a served export's 108 ms): every one, as the install compiles them
WARM_UPS = ("ultraglide.compile_kernels.compile_all",)
IMPORT_TIME_VARIABLES = ("NUMBA_", "OMP_", "OPENBLAS_", "MKL_", "PYTHON", "LD_", "MALLOC_", "MPL")

SERVER = r'''
import importlib, json, os, runpy, selectors, signal, socket, sys
control = socket.socket(fileno=int(sys.argv[1]))
for name in json.loads(sys.argv[2]):
    importlib.import_module(name)
for name in json.loads(sys.argv[3]):
    importlib.import_module(name)
loaded = [name for name in json.loads(sys.argv[4]) if name in sys.modules]
if loaded:
    sys.exit(f"preloading loaded {loaded}")
if "numba" in sys.modules:  # numba's CPU target, which every process builds at its first compiled function
    from numba.core.registry import cpu_target  # (cached or not; 0.2 s): the library's start-up, not ours
    cpu_target.target_context.refresh()
    cpu_target.target_context.codegen()
for name in json.loads(sys.argv[5]):
    module, _, function = name.rpartition(".")
    getattr(importlib.import_module(module), function)()
import gc  # the children's collector leaves the preloaded objects alone: a collection would write to every
gc.collect()  # page that holds one, copying the server's memory into each child
gc.freeze()
sys.stderr.flush()
control.sendall(b"ready\n")
wake_read, wake_write = socket.socketpair()
wake_read.setblocking(False)
wake_write.setblocking(False)
signal.set_wakeup_fd(wake_write.fileno())
signal.signal(signal.SIGCHLD, lambda *_: None)
replies = {}

def serve():
    selector = selectors.DefaultSelector()
    selector.register(control, selectors.EVENT_READ, "control")
    selector.register(wake_read, selectors.EVENT_READ, "wake")
    while True:
        for key, _ in selector.select():
            if key.data == "wake":
                try:
                    wake_read.recv(4096)
                except BlockingIOError:
                    pass
                reap()
                continue
            message, fds, _, _ = socket.recv_fds(control, 64, 3)
            if not message:
                return
            stdout, stderr, reply_fd = fds
            reply = socket.socket(fileno=reply_fd)
            size, body = int(message), b""
            while len(body) < size:
                chunk = reply.recv(size - len(body))
                if not chunk:
                    break
                body += chunk
            request = json.loads(body)
            pid = os.fork()
            if pid == 0:
                selector.close()
                return run_child(request, stdout, stderr, reply)
            os.close(stdout)
            os.close(stderr)
            replies[pid] = reply
            reply.sendall(json.dumps({"pid": pid}).encode() + b"\n")
        reap()

def reap():
    while replies:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        reply = replies.pop(pid, None)
        if reply is not None:
            try:
                reply.sendall(json.dumps({"returncode": os.waitstatus_to_exitcode(status)}).encode() + b"\n")
            except OSError:
                pass
            reply.close()

def run_child(request, stdout, stderr, reply):
    signal.set_wakeup_fd(-1)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    for other in replies.values():
        other.close()
    reply.close()
    control.close()
    wake_read.close()
    wake_write.close()
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(stdout, 1)
    os.dup2(stderr, 2)
    for fd in (null, stdout, stderr):
        os.close(fd)
    import faulthandler  # SIGUSR1 prints every thread's stack on stderr: what a test that waited too long reports
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    if request.get("file_size_limit") is not None:  # a full disk, as the kernel refuses a file past RLIMIT_FSIZE
        import resource
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
        resource.setrlimit(resource.RLIMIT_FSIZE, (request["file_size_limit"],) * 2)
    os.environ.clear()
    os.environ.update(request["env"])
    os.chdir(request["cwd"])
    sys.argv = [request["module"], *request["args"]]
    return request["module"]

def leave(code, interrupted):
    """The interpreter's shutdown up to its flush of the standard streams, then the exit: the teardown of the
    modules that follows would write to every page of the preloaded heap (copy-on-write, 0.15 s of CPU a command)"""
    import atexit, threading
    threading._shutdown()  # non-daemon threads joined, as at the interpreter's exit
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception as error:  # as the interpreter says it, and its status then
            sys.unraisablehook(type("Unraisable", (), {"exc_type": type(error), "exc_value": error, "err_msg": None,
                                                        "exc_traceback": error.__traceback__, "object": stream}))
            code = 120
    if interrupted:  # an uncaught KeyboardInterrupt: the interpreter ends by SIGINT
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGINT)
    os._exit(code)

module = serve()
if module:
    del serve, reap, run_child, replies, control, wake_read, wake_write
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
    except SystemExit as exit_:
        if exit_.code is None or isinstance(exit_.code, int):
            leave(exit_.code or 0, False)
        print(exit_.code, file=sys.stderr)
        leave(1, False)
    except BaseException as error:
        sys.excepthook(type(error), error, error.__traceback__)
        leave(1, isinstance(error, KeyboardInterrupt))
    leave(0, False)
'''


class CliServer:
    """One per test worker: forks the command from a process that has its libraries imported."""

    def __init__(self) -> None:
        import tempfile

        self._env = dict(os.environ)
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)  # one request a message
        with tempfile.TemporaryFile() as said:
            self._process = subprocess.Popen(
                [sys.executable, "-c", SERVER, str(theirs.fileno()), json.dumps(PRELOAD), json.dumps(PRELOAD_OURS),
                 json.dumps(NOT_PRELOADED), json.dumps(WARM_UPS)],
                pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=said, env=self._env)
            theirs.close()
            self._control = ours
            ours.settimeout(300)
            ready = ours.recv(6) == b"ready\n"
            ours.settimeout(None)
            said.seek(0)
            told = said.read().decode(errors="replace")
            if told.startswith("preloading loaded"):  # a module of ours now pulls a sound or window library in
                raise RuntimeError(f"tests/cli_server.py: {told.strip()}; take it out of PRELOAD_OURS")
            # a warning printed while importing would be printed by every real run and hidden in a forked one
            self._usable = ready and not told

    def serves(self, env: dict[str, str]) -> bool:
        """Whether a command with this environment may run forked from the server."""
        if not self._usable or self._process.poll() is not None:
            return False
        names = set(env) | set(self._env)
        return not any(name.startswith(IMPORT_TIME_VARIABLES) and env.get(name) != self._env.get(name)
                       for name in names)

    def _request(self, args, env, cwd, stdout: int, stderr: int, file_size_limit: int | None,
                 module: str = "ultraglide") -> socket.socket:
        """Ask for ``ultraglide ARGS`` writing to the descriptors ``stdout`` and ``stderr``; the request's own socket,
        on which the server says the child's pid, then its exit status."""
        ours, theirs = socket.socketpair()
        request = json.dumps({"module": module, "args": args, "env": env, "cwd": str(cwd),
                              "file_size_limit": file_size_limit}).encode()
        try:  # the outputs and the request's own socket with the request's size; the request (of any size) on it
            socket.send_fds(self._control, [str(len(request)).encode()], [stdout, stderr, theirs.fileno()])
        finally:
            theirs.close()
        ours.sendall(request)
        return ours

    def start(self, args: list[str], env: dict[str, str], cwd: Path, stdout: int, stderr: int,
              file_size_limit: int | None = None, module: str = "ultraglide") -> ServedCommand:
        """The command running, as ``subprocess.Popen`` would start it with these output descriptors
        (``module``: ``python -m`` of another module, importable from ``cwd``)."""
        return ServedCommand(self._request(args, env, cwd, stdout, stderr, file_size_limit, module), args)

    def run(self, args: list[str], env: dict[str, str], cwd: Path, timeout: float,
            file_size_limit: int | None = None, module: str = "ultraglide") -> subprocess.CompletedProcess:
        out_read, out_write = os.pipe()
        err_read, err_write = os.pipe()
        try:
            ours = self._request(args, env, cwd, out_write, err_write, file_size_limit, module)
        finally:
            for fd in (out_write, err_write):
                os.close(fd)
        deadline = time.monotonic() + timeout
        chunks = {out_read: [], err_read: []}
        replies = b""
        pid = None
        with selectors.DefaultSelector() as selector:
            selector.register(out_read, selectors.EVENT_READ)
            selector.register(err_read, selectors.EVENT_READ)
            selector.register(ours, selectors.EVENT_READ)
            open_streams = 3
            while open_streams:
                left = deadline - time.monotonic()
                if left <= 0:
                    if pid is not None:
                        try:
                            os.kill(pid, 9)
                        except ProcessLookupError:
                            pass
                    for fd in chunks:
                        os.close(fd)
                    ours.close()
                    raise subprocess.TimeoutExpired(["ultraglide", *args], timeout)
                for key, _ in selector.select(min(left, 1.0)):
                    if key.fileobj is ours:
                        data = ours.recv(4096)
                        replies += data
                        if pid is None and b"\n" in replies:
                            pid = json.loads(replies.split(b"\n", 1)[0])["pid"]
                    else:
                        data = os.read(key.fileobj, 1 << 16)
                        if data:
                            chunks[key.fileobj].append(data)
                    if not data:
                        selector.unregister(key.fileobj)
                        open_streams -= 1
        for fd in chunks:
            os.close(fd)
        ours.close()
        lines = [json.loads(line) for line in replies.splitlines() if line.strip()]
        returncode = next((line["returncode"] for line in lines if "returncode" in line), None)
        if returncode is None:
            raise RuntimeError(f"the test's command server lost ultraglide {' '.join(args)}")
        return subprocess.CompletedProcess(["ultraglide", *args], returncode, _text(b"".join(chunks[out_read])),
                                           _text(b"".join(chunks[err_read])))

    def close(self) -> None:
        self._control.close()
        try:
            self._process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()


class ServedCommand:
    """A command the server forked, while it runs: ``pid``, ``poll``, ``wait``, ``send_signal``, ``kill`` and
    ``returncode`` as ``subprocess.Popen``'s. The server reaps the child and says its exit status on the request's
    socket; signals go through a pidfd, so that none reaches another process that got the pid since."""

    def __init__(self, reply: socket.socket, args: list[str]) -> None:
        self.args = ["ultraglide", *args]
        self.stdout = self.stderr = None  # (start_cli's pipes, when it makes them)
        self._reply = reply
        self._said = b""
        self.returncode = None
        reply.settimeout(300)
        while b"\n" not in self._said:
            chunk = reply.recv(4096)
            if not chunk:
                raise RuntimeError(f"the test's command server lost ultraglide {' '.join(args)}")
            self._said += chunk
        self.pid = json.loads(self._said.split(b"\n", 1)[0])["pid"]
        try:
            self._pidfd = os.pidfd_open(self.pid)
        except ProcessLookupError:  # already gone and reaped: its status is on the way
            self._pidfd = None

    def _read(self, timeout: float | None) -> None:
        if self.returncode is not None:
            return
        self._reply.settimeout(timeout)
        try:
            chunk = self._reply.recv(4096)
        except (TimeoutError, BlockingIOError):
            return
        self._said += chunk
        lines = [json.loads(line) for line in self._said.split(b"\n")[:-1] if line.strip()]  # whole lines
        code = next((line["returncode"] for line in lines if "returncode" in line), None)
        if code is not None or not chunk:
            if code is None:
                raise RuntimeError(f"the test's command server lost {' '.join(self.args)}")
            self.returncode = code
            self._reply.close()
            if self._pidfd is not None:
                os.close(self._pidfd)

    def poll(self) -> int | None:
        self._read(0)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.returncode is None:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                raise subprocess.TimeoutExpired(self.args, timeout)
            self._read(left)
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple:
        """Read the pipes start_cli made to their end, then wait for the exit: (stdout, stderr), as Popen's."""
        deadline = None if timeout is None else time.monotonic() + timeout
        streams = [stream for stream in (self.stdout, self.stderr) if stream is not None]
        chunks = {stream.fileno(): [] for stream in streams}
        with selectors.DefaultSelector() as selector:
            for stream in streams:
                selector.register(stream.fileno(), selectors.EVENT_READ)
            while selector.get_map():
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    raise subprocess.TimeoutExpired(self.args, timeout)
                for key, _ in selector.select(left):
                    data = os.read(key.fd, 1 << 16)
                    if data:
                        chunks[key.fd].append(data)
                    else:
                        selector.unregister(key.fd)
        self.wait(None if deadline is None else max(deadline - time.monotonic(), 0.01))
        said = []
        for stream in (self.stdout, self.stderr):
            if stream is None:
                said.append(None)
                continue
            data = b"".join(chunks[stream.fileno()])
            said.append(_text(data) if "b" not in stream.mode else data)
            stream.close()
        return tuple(said)

    def send_signal(self, signum: int) -> None:
        if self.poll() is None and self._pidfd is not None:
            try:
                signal.pidfd_send_signal(self._pidfd, signum)
            except ProcessLookupError:  # it has exited: the server reports it
                pass

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def stacks(self, stderr) -> str:
        """Every thread's Python stack, which the command prints on its stderr (SIGUSR1, the server's faulthandler)
        and which is read here from ``stderr``, its read end (within 10 s): for a test whose wait for it ran out,
        to say where it was."""
        self.send_signal(signal.SIGUSR1)
        said, wait_s = b"", 10.0
        while select.select([stderr], [], [], wait_s)[0]:  # until it has been quiet for half a second
            chunk = os.read(stderr.fileno(), 1 << 16)
            if not chunk:
                break
            said, wait_s = said + chunk, 0.5
        return said.decode(errors="replace")

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def _text(data: bytes) -> str:
    """As subprocess's text mode reads a pipe: the locale's encoding, universal newlines."""
    import io
    import locale

    return io.TextIOWrapper(io.BytesIO(data), encoding=locale.getpreferredencoding(False)).read()
