"""Write files so that a reader never sees half of one, and a stop signal never leaves a temporary file.

Every file a command writes goes through :func:`atomic_path`, the commands' door to the one atomic writer
(:class:`ultraglide.atomic.AtomicFile`: what it does with devices, pipes, directories and links, and how it
names and clears its temporary files). Here it gains the clean-up against stop signals: the temporary file
is removed on any way out but success, an exception (a full disk, a file too large), Ctrl-C, SIGTERM or
SIGHUP (which ``ultraglide``'s ``main`` turns into exceptions), and its rename and removal are held
against a second signal (see :mod:`ultraglide.apps.cli.signals`).
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterator
from pathlib import Path

from ultraglide.apps.cli.errors import UsageError
from ultraglide.apps.cli.signals import held

from ultraglide.atomic import AtomicFile, check_output, check_output_folder


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield the path to write for ``path``; put it in place if the block succeeds.

    Whatever the block writes there must be complete (files closed, errors raised) when it ends."""
    target = AtomicFile(path)
    try:
        yield target.temporary
        with held():
            target.commit()
    except BaseException as error:
        translated = target.user_error(error)
        if translated is not error:
            raise translated from None
        raise
    finally:
        with held():
            target.discard()


def check_outputs(args) -> None:
    """Check every output the command's options name (:func:`ultraglide.apps.cli.options.output_option`) before
    it runs: :class:`ultraglide.atomic.OutputRefused`, one line naming the option, for what writing would refuse
    later (a directory, a disk, a socket, a pipe nobody reads, a missing or read-only folder). ``main`` calls it
    for every command."""
    from ultraglide.apps.cli.options import OUTPUTS

    declared = getattr(args, OUTPUTS, None) or {}
    written: dict[str, Path] = {}  # every file the command would write, by how the person named it
    for dest, (option, kind, also) in declared.items():
        value = getattr(args, dest, None)
        if value is None:
            continue
        if kind == "folder":
            check_output_folder(value, option)
            if os.path.isdir(value):  # the files it writes into the folder, where the folder already holds them
                for name in also:
                    check_output(Path(value) / name, option, named=str(Path(value) / name))
                    written[f"{option} {value}, its {name}"] = Path(value) / name
            continue
        named = None
        if kind == "device":
            value, named = _wav_target(value), value
            if value is None:
                continue
            kind = "wav"
        check_output(value, option, kind=kind, named=named)
        written[option] = Path(value)
        for suffix in also:
            check_output(Path(value).with_suffix(suffix), f"{option} (its {suffix.lstrip('.').upper()} beside it)")
            written[f"{option} (its {suffix.lstrip('.').upper()} beside it)"] = Path(value).with_suffix(suffix)
    refuse_overlaps(written, _files_named(args, {*declared, getattr(args, "output_may_replace", None)}))


def _files_named(args, skip) -> dict[str, Path]:
    """What the command's other arguments name that is a file (a texture, a touch log, a finger's force script, a
    model's ``table:`` CSV ...): what it reads, whichever option names it, so that no output replaces it."""
    found: dict[str, Path] = {}
    for dest, value in vars(args).items():
        if dest in skip or dest == "checked_outputs":
            continue
        items = value if isinstance(value, list | tuple) else (value,)
        for number, item in enumerate(items, 1):
            if not isinstance(item, str):
                continue
            path = item.removeprefix("table:")
            with contextlib.suppress(OSError, ValueError):
                if os.path.isfile(path):
                    found[f"the {dest.replace('_', ' ')}" + (f" {number}" if len(items) > 1 else "")] = Path(path)
    return found


def _wav_target(url: str) -> str | None:
    """The file a device URL writes (``wav:PATH``), or None (another kind, or a URL the command refuses)."""
    if not url.startswith("wav:"):
        return None
    from ultraglide.devices.errors import DeviceError
    from ultraglide.devices.urls import parse_device_url

    try:
        return parse_device_url(url).target or None
    except DeviceError:
        return None


def _identities(path: str | Path) -> set[tuple]:
    """What names ``path``'s file: its resolved path (links and ``..`` followed, whether it exists or not) and,
    when it exists, its device and inode (which also catches hard links)."""
    found: set[tuple] = {("path", os.path.realpath(path))}
    with contextlib.suppress(OSError, ValueError):
        info = os.stat(path)
        found.add(("inode", info.st_dev, info.st_ino))
    return found


def _is_character_device(path: str | Path) -> bool:
    with contextlib.suppress(OSError, ValueError):
        return stat.S_ISCHR(os.stat(path).st_mode)
    return False


def refuse_overlaps(outputs: dict[str, str | Path | None], inputs: dict[str, str | Path | None] | None = None) -> None:
    """Refuse, before anything is read or written, an output that is also an input or two outputs that are one
    file, in one line. Keys are what the person typed (``-o``, ``--envelope-csv``, ``the texture``); values
    the paths (None: not given). Files are compared as what they are: through symbolic links, ``..``, hard links.
    A character device may take several outputs (``/dev/null`` twice discards both)."""
    seen: list[tuple[str, str | Path, set[tuple]]] = []
    for label, path in (inputs or {}).items():
        if path is not None:
            seen.append((label, path, _identities(path)))
    inputs_count = len(seen)
    for label, path in outputs.items():
        if path is None:
            continue
        identities = _identities(path)
        for number, (other_label, other_path, other) in enumerate(seen):
            if identities & other:
                if number < inputs_count:
                    raise UsageError(f"{path} ({label}) is also {other_label} ({other_path}), which is read: "
                                     "writing it would destroy it; choose another output name")
                if not _is_character_device(path):
                    raise UsageError(f"{path} ({label}) and {other_path} ({other_label}) are the same file; "
                                     "give each output its own name")
        seen.append((label, path, identities))


def texture_file(spec: str | None) -> Path | None:
    """The file a TEXTURE argument reads: the path given, or the bundled library file of that name."""
    if spec is None:
        return None
    if spec.startswith("rig:"):  # a rig's plate (apps.commands.plate_choice): the rig file is what is read
        return Path(spec[4:])
    if os.path.lexists(spec):
        return Path(spec)
    from ultraglide.textures.library import LIBRARY_DIR

    bundled = LIBRARY_DIR / f"{spec}.png"
    return bundled if "/" not in spec and bundled.is_file() else None


def model_file(spec: str | None) -> Path | None:
    """The file a ``--model`` reads: ``table:FILE.csv`` or ``CAL.toml``, also wrapped in ``dynamic:`` or
    ``speed:S:``; None for a model by name."""
    if spec is None:
        return None
    while spec.startswith(("dynamic:", "speed:")):
        inner = spec.partition(":")[2]  # dynamic:NAME's NAME, or speed:S:NAME's S:NAME
        spec = inner if spec.startswith("dynamic:") else inner.partition(":")[2]
    if spec.startswith("table:"):
        return Path(spec.removeprefix("table:"))
    return Path(spec) if spec.endswith(".toml") else None


def profile_file(spec: str | None) -> Path | None:
    """The file a ``--profile`` reads: the path given, or the bundled profile of that name; for ``rig:PATH``, the
    rig file."""
    if spec is None:
        return None
    if spec.startswith("rig:"):  # a rig's plate (apps.commands.plate_choice): the rig file is what is read
        return Path(spec[4:])
    if os.path.lexists(spec):
        return Path(spec)
    from ultraglide.devices.profiles import PROFILE_DIR

    bundled = PROFILE_DIR / f"{spec}.toml"
    return bundled if "/" not in spec and bundled.is_file() else None


def render_inputs(args) -> dict[str, Path | None]:
    """The files ``export`` and ``play`` read, keyed by the option that names each."""
    return {"the texture": texture_file(args.texture), "--trajectory": args.trajectory and Path(args.trajectory),
            "--model": model_file(args.model), "--profile": profile_file(args.profile),
            "--effects": getattr(args, "effects", None) and Path(args.effects)}
