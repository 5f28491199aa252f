"""The tests' command server (tests/cli_server.py) ends a command as a real ``python -m`` process ends: the same
exit status, output and last words, for each way a program ends (returns, ``sys.exit`` with a number or a text,
an uncaught exception, Ctrl-C, a standard stream it cannot flush), with its non-daemon threads and atexit
handlers run. Each case is a small module run both ways from the same folder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pytest
from conftest import _cli_server

PROGRAMS = {
    "returns": """
        import atexit, sys, threading
        def after_main():
            threading.main_thread().join()  # ends only once the main thread has: joined at the exit
            print("the thread, after main", flush=True)
        threading.Thread(target=after_main).start()
        atexit.register(lambda: print("atexit"))
        sys.stdout.write("buffered, no newline; ")
        """,
    "exits_with_a_number": "import sys; print('leaving'); sys.exit(3)",
    "exits_with_a_text": "import sys; sys.exit('what went wrong')",
    "raises": "raise ValueError('a bad value')",
    "cannot_flush": "import sys; sys.stdout = open('/dev/full', 'w'); print('kept in the buffer')",  # ENOSPC
}


def served(module: str, folder, **kwargs):
    server = _cli_server()
    if server is None or not server.serves(dict(os.environ)):
        pytest.skip("the command server is turned off (ULTRAGLIDE_TEST_FORK=0)")
    return server, dict(module=module, args=[], env=dict(os.environ), cwd=folder, **kwargs)


def last_line(text: str) -> str:
    return text.strip().splitlines()[-1] if text.strip() else ""


@pytest.mark.parametrize("name", PROGRAMS)
def test_a_served_program_ends_as_a_real_process_does(tmp_path, name):
    (tmp_path / f"{name}.py").write_text(textwrap.dedent(PROGRAMS[name]))
    real = subprocess.run([sys.executable, "-m", name], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    server, request = served(name, tmp_path)
    forked = server.run(request.pop("args"), timeout=120, **request)
    assert (forked.returncode, forked.stdout) == (real.returncode, real.stdout), (forked, real)
    assert last_line(forked.stderr) == last_line(real.stderr), (forked.stderr, real.stderr)
    # the cases differ from one another: the comparison above is not between two empty results
    assert real.returncode == {"returns": 0, "exits_with_a_number": 3, "exits_with_a_text": 1, "raises": 1,
                               "cannot_flush": 120}[name], real


def test_ctrl_c_ends_a_served_program_by_sigint_as_a_real_process(tmp_path):
    (tmp_path / "waits.py").write_text(  # Python's own Ctrl-C, whatever the worker's state passed on to the program
        "import signal, threading\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
        "signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})\n"
        "print('waiting', flush=True)\nthreading.Event().wait()\n")
    real = subprocess.Popen([sys.executable, "-m", "waits"], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    server, request = served("waits", tmp_path)
    out_read, out_write = os.pipe()
    err_read, err_write = os.pipe()
    forked = server.start(request.pop("args"), stdout=out_write, stderr=err_write, **request)
    os.close(out_write)
    os.close(err_write)
    with open(out_read) as forked_out, open(err_read) as forked_err:
        for process, out in ((real, real.stdout), (forked, forked_out)):
            assert out.readline() == "waiting\n"  # its wait has begun
            process.send_signal(signal.SIGINT)
        try:
            forked.wait(timeout=120)
        except subprocess.TimeoutExpired:  # (once in a whole suite, before the program set its own Ctrl-C)
            with open(f"/proc/{forked.pid}/status") as status:
                masks = [line.strip() for line in status if line.startswith(("SigBlk", "SigIgn", "SigCgt"))]
            stacks = forked.stacks(forked_err)
            forked.kill()
            raise AssertionError(f"the served program outlived Ctrl-C by 120 s: {masks}\n{stacks}") from None
        assert forked.returncode == real.wait(timeout=120) == -signal.SIGINT
        assert last_line(forked_err.read()) == last_line(real.stderr.read()) == "KeyboardInterrupt"
    real.stdout.close()
    real.stderr.close()
