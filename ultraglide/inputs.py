"""Reading a file a person named, safely: regular files only, bounded sizes, parsers' failures in one line.

Every loader of ours opens its path through :func:`open_input` (or :func:`read_input` for small files read
whole): the path is looked at first (``stat``, following links) and anything but a regular file is refused
in one line without being opened for reading — a named pipe would block until a writer came, a device
(``/dev/zero``, ``/dev/urandom``) would never end, a directory or a socket cannot be read as a file. The open
itself is non-blocking and what it opened is checked again (``fstat``), so a path swapped for a pipe between
the look and the open is refused too.

:func:`parse_json` and :func:`parse_toml` turn every failure of the parsers into one line: syntax, text that
is not UTF-8, nesting deeper than any file of ours has (:data:`MAX_DEPTH`; the parsers would otherwise run
out of recursion), integers longer than Python converts (they are read as floats, so ranges refuse them by
value: an integer of 5 000 digits is infinite, not a crash).

Every function takes ``error``, the exception type the caller raises (``TextureError``, ``ModelError`` ...),
so a package's callers keep catching its own errors; ``what`` names the kind of file in messages.

This module imports nothing of ours: every package may use it.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import stat
from pathlib import Path
from typing import BinaryIO

MAX_DEPTH = 64  # the deepest file of ours (an effects description) nests about 40 levels
MAX_SMALL_FILE_BYTES = 4 << 20  # a profile, a calibration, an effects description, a session: a few KB
_LONGEST_EXACT_INT = 18  # digits: any longer integer is read as a float (no file of ours holds one)
# a TOML key of many dotted parts (``a.b.c = 1``, ``[a.b.c]``): tomllib takes time quadratic in a key's parts
# (60 000 parts, 120 KB: minutes), so chains of parts are looked for before parsing (possessive: linear time);
# a number (1.5) or a version (1.2.3) in a string is a chain of two or three
_TOML_PART = r"""(?:[\w-]++|"[^"\n]*+"|'[^'\n]*+')"""


def _kind(mode: int) -> str:
    for test, words in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a named pipe"),
                        (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                        (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return words
    return "not a regular file"


def _refusal(path, mode: int, what: str, error: type[Exception]) -> Exception:
    kind = _kind(mode)
    why = "" if stat.S_ISDIR(mode) else "; ultraglide reads regular files only (a pipe or a device could wait " \
                                        "or run forever)"
    return error(f"{path}: is {kind}, not {_a(what)}{why}")


def _a(what: str) -> str:
    return f"{'an' if what[:1] in 'aeiou' else 'a'} {what}"


def _cannot(path, problem: OSError, what: str, error: type[Exception]) -> Exception:
    if isinstance(problem, FileNotFoundError | NotADirectoryError):
        return error(f"{path}: no such {what}")
    return error(f"{path}: cannot read it ({(problem.strerror or str(problem)).lower()})")


def check_input(path: str | Path, what: str, error: type[Exception]) -> os.stat_result:
    """The ``stat`` of ``path`` if it is a regular file (links followed); else ``error`` in one line."""
    try:
        info = os.stat(path)
    except (OSError, ValueError) as problem:  # ValueError: a NUL byte in the path
        if isinstance(problem, ValueError):
            raise error(f"{path!r}: not a usable file name") from None
        raise _cannot(path, problem, what, error) from None
    if not stat.S_ISREG(info.st_mode):
        raise _refusal(path, info.st_mode, what, error)
    return info


def open_input(path: str | Path, what: str, error: type[Exception]) -> BinaryIO:
    """``path`` opened for reading in binary, if it is a regular file; ``error`` (one line) if it is not,
    if it does not exist or cannot be read. Never blocks on a pipe or a device."""
    check_input(path, what, error)
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except OSError as problem:
        raise _cannot(path, problem, what, error) from None
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):  # swapped between the look and the open
            raise _refusal(path, mode, what, error)
        fcntl.fcntl(descriptor, fcntl.F_SETFL, fcntl.fcntl(descriptor, fcntl.F_GETFL) & ~os.O_NONBLOCK)
        return os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise


def read_input(path: str | Path, what: str, error: type[Exception], max_bytes: int = MAX_SMALL_FILE_BYTES) -> bytes:
    """The whole of a small regular file (:func:`open_input`); more than ``max_bytes`` is refused unread."""
    with open_input(path, what, error) as stream:
        data = stream.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise error(f"{path}: more than {max_bytes / (1 << 20):g} MiB, far larger than {_a(what)} ever is; "
                    "is it the right file?")
    return data


def decode_text(data: bytes | str, where: str, what: str, error: type[Exception]) -> str:
    """UTF-8 text (a byte-order mark dropped); ``error`` naming ``where`` if it is not."""
    if isinstance(data, str):
        return data
    try:
        return data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as problem:
        raise error(f"{where}: not UTF-8 text at byte {problem.start}; {_a(what)} is a text file") from None


def _integer(text: str) -> int | float:
    return int(text) if len(text.lstrip("-")) <= _LONGEST_EXACT_INT else float(text)


def parse_json(data: bytes | str, where: str, error: type[Exception], what: str = "JSON file",
               max_depth: int = MAX_DEPTH):
    """A JSON document; any failure is ``error`` naming ``where``, in one line. Integers longer than 18
    digits are read as floats; ``NaN`` and ``Infinity`` stay floats (ranges refuse them)."""
    text = decode_text(data, where, what, error)
    try:
        document = json.loads(text, parse_int=_integer)
    except RecursionError:
        raise error(f"{where}: nested too deeply (more than {max_depth} levels, which no {what} has)") from None
    except ValueError as problem:  # JSONDecodeError, and anything else the parser refuses
        raise error(f"{where}: not valid JSON ({_first_line(problem)})") from None
    _check_depth(document, where, error, what, max_depth)
    return document


def parse_toml(data: bytes | str, where: str, error: type[Exception], what: str = "TOML file",
               max_depth: int = MAX_DEPTH) -> dict:
    """A TOML document; any failure is ``error`` naming ``where``, in one line. Integers beyond 64 bits are
    read as floats (infinite when beyond a float's range), as :func:`parse_json` does."""
    import tomllib

    text = decode_text(data, where, what, error)
    if _long_toml_key(text, max_depth):
        raise error(f"{where}: nested too deeply (a key of more than {max_depth} parts, which no {what} has)")
    try:
        document = tomllib.loads(text)
    except RecursionError:
        raise error(f"{where}: nested too deeply (more than {max_depth} levels, which no {what} has)") from None
    except ValueError as problem:  # TOMLDecodeError, and an integer longer than Python converts
        reason = _first_line(problem)
        if "integer string conversion" in reason:
            reason = "an integer of thousands of digits"
        raise error(f"{where}: not a valid TOML file ({reason})") from None
    _check_depth(document, where, error, what, max_depth, widen_integers=True)
    return document


def _long_toml_key(text: str, parts: int) -> bool:
    """Whether TOML ``text`` has a dotted key of more than ``parts`` parts (or a string that looks like one)."""
    if text.count(".") < parts:
        return False
    chain = re.compile(rf"""(?<![\w"'.-]){_TOML_PART}(?:[ \t]*+\.[ \t]*+{_TOML_PART}){{{parts},}}""")
    return chain.search(text) is not None


def _check_depth(document, where: str, error: type[Exception], what: str, max_depth: int,
                 widen_integers: bool = False) -> None:
    """Refuse nesting deeper than ``max_depth`` (walked without recursion); optionally make integers beyond
    64 bits floats, in place."""
    stack = [(document, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            keys = list(value)
        elif isinstance(value, list):
            keys = range(len(value))
        else:
            continue
        if depth > max_depth:
            raise error(f"{where}: nested too deeply (more than {max_depth} levels, which no {what} has)")
        for key in keys:
            child = value[key]
            if widen_integers and isinstance(child, int) and not isinstance(child, bool) and abs(child) >= 1 << 63:
                value[key] = _widened(child)
            elif isinstance(child, dict | list):
                stack.append((child, depth + 1))


def _widened(number: int) -> float:
    try:
        return float(number)
    except OverflowError:
        return float("inf") if number > 0 else float("-inf")


def _first_line(problem: BaseException) -> str:
    text = str(problem).strip()
    return text.splitlines()[0] if text else type(problem).__name__


def shown(text) -> str:
    """A file's text as a message quotes it: as written when it is printable, else quoted with its escapes
    (``'\\x1b]0;…'``), so that what a file holds never reaches a terminal or a log raw and an error stays one
    line."""
    text = str(text)
    return text if text.isprintable() else repr(text)


def some_of(names, count: int = 5) -> str:
    """A bounded listing for a message: ``a, b, c`` or ``a, b, c, d, e and 9,995 more`` (each shortened, and
    quoted with its escapes when it holds a control character, as :func:`shown` does)."""
    names = [shown(name) for name in names]
    listed = ", ".join(name if len(name) <= 40 else name[:39] + "…" for name in names[:count])
    return listed if len(names) <= count else f"{listed} and {len(names) - count:,} more"
