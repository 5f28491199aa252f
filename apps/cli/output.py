"""What the command prints is safe for a terminal and for a parser.

Text from files (a texture's name and description, a profile's name, a path) may hold control characters:
escape sequences that retitle or clear a terminal, bidirectional overrides that make text read backwards,
carriage returns that overwrite a line. :func:`printable` writes each such character as its ``\\uXXXX``
escape, which a person can read and which is also a valid escape inside a JSON string. ``main`` installs
:class:`PrintableStream` over standard output and standard error for the length of a command, so nothing
printed anywhere reaches the terminal raw; newlines and tabs pass (and carriage returns on standard error,
where progress bars redraw their line).

:func:`json_text` is strict JSON: no ``NaN`` or ``Infinity`` (not JSON; most parsers refuse them), which
become ``null``. Every ``--json`` output goes through :func:`print_json`.
"""

from __future__ import annotations

import json
import math
import re
import sys
import threading

# C0 and C1 controls, DEL, line and paragraph separators, bidirectional controls and other invisible format
# characters, and lone surrogates (undecodable bytes of a file name)
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ufff9-\ufffb"
                     "\ud800-\udfff]")
MAX_LINE = 600  # characters of one error or warning line


def _escape(match: re.Match) -> str:
    return f"\\u{ord(match.group()):04x}"


def printable(text: str, keep: str = "") -> str:
    """``text`` with every control, bidirectional or invisible format character written as ``\\uXXXX``
    (those in ``keep`` pass)."""
    if keep:
        return _UNSAFE.sub(lambda m: m.group() if m.group() in keep else _escape(m), text)
    return _UNSAFE.sub(_escape, text)


def one_line(text: str, limit: int = MAX_LINE) -> str:
    """``text`` printable, on one line, and at most about ``limit`` characters (the rest counted)."""
    text = printable(text)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}… ({len(text) - limit:,} more characters)"


class PrintableStream:
    """A text stream that writes :func:`printable` text to another (``keep``: the controls let through)."""

    def __init__(self, stream, keep: str = "\n\t"):
        self.stream = stream
        self.keep = keep

    def write(self, text: str) -> int:
        self.stream.write(printable(text, self.keep))
        return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name):  # flush, fileno, isatty, encoding, buffer ...
        return getattr(self.stream, name)


def _finite(value):
    """``value`` with every non-finite float (NaN, ±inf; numpy's too) replaced by None."""
    if isinstance(value, float) or type(value).__name__ in ("float32", "float64", "float16"):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(item) for item in value]
    return value


def json_text(value, **options) -> str:
    """Strict JSON for ``value`` (``json.dumps`` options pass): NaN and infinities become null."""
    options.setdefault("ensure_ascii", False)
    return json.dumps(_finite(value), allow_nan=False, **options)


_LINES = threading.Lock()  # events come from several threads (a plate's reader, its output stage)


def print_line(text: str, file=None) -> None:
    """Print one whole line, text and newline in one write: lines printed from two threads never run into
    each other (``print`` writes the newline separately)."""
    stream = file or sys.stdout
    with _LINES:
        stream.write(text + "\n")
        stream.flush()


def print_json(value, file=None) -> None:
    """Print ``value`` as one line of strict JSON, terminal-safe (see the module's docstring)."""
    print_line(printable(json_text(value)), file)


__all__ = ["MAX_LINE", "PrintableStream", "json_text", "one_line", "print_json", "print_line", "printable"]
