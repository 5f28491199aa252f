"""``demo --watch``: notice when a texture's file or its source image changes, and load it again.

The demo's loop calls :meth:`TextureWatcher.poll` from its event wait's timeout (every 200 ms), so
watching costs a few ``stat`` calls a poll. A changed file is decoded on a thread of its own (a large
image takes seconds), the window drawing meanwhile; a later poll takes the texture when it is ready.
A file counts as changed when its (inode, size, mtime) differs from what was loaded and has stayed the
same for one poll, so neither an in-place rewrite caught half-written nor an editor's rename is loaded
before it is whole.

Whatever the file becomes, the demo keeps the texture last loaded and says what is wrong, one line each in
:attr:`TextureWatcher.errors` (shown on the status line), until the file loads again: removed (for a whole
poll: an editor's rename takes less), a loop of links, a named pipe or a device (refused by the loaders
without being opened), a directory, half written, damaged, deeply nested or with absurd numbers in its
metadata. A file that failed is tried again only once it changes, so a bad file costs a ``stat`` a poll.

A texture file loads as it is; a plain image is authored with the defaults (as the demo does at
start-up); when the source image a texture file was authored from changes, the texture is authored
again from it with the options recorded in the file (the file itself is not rewritten).
"""

from __future__ import annotations

import dataclasses
import errno
import os
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

POLL_S = 0.2


def _look(path: Path) -> tuple[tuple[int, int, int] | None, str | None]:
    """The file's (inode, size, mtime), or None and why it cannot be looked at."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return None, "it was removed"
    except ValueError:
        return None, "not a usable file name"
    except OSError as error:
        if error.errno == errno.ELOOP:
            return None, "it is a loop of symbolic links"
        return None, f"cannot look at it ({(error.strerror or str(error)).lower()})"
    return (info.st_ino, info.st_size, info.st_mtime_ns), None


@dataclass
class _Watched:
    index: int  # in the demo's list of textures
    path: Path  # the file the texture came from
    source: Path | None  # the image it was authored from, when that is another file that exists
    keys: dict  # path → the key last loaded
    seen: dict  # path → the key seen at the last poll
    failed: dict | None = None  # path → key of the files as they were when loading failed
    error: str = ""  # why, while they stay so
    loading: _Load | None = None  # a load under way on its own thread


class _Load:
    """One load of a changed file on a daemon thread: its outcome in ``texture`` or ``error`` once ``done``."""

    def __init__(self, load, watched: _Watched, changed: Path):
        self.changed = changed
        self.seen = dict(watched.seen)  # the files' keys when the load began: loaded, they are what was loaded
        self.texture = None
        self.error = ""
        self.done = threading.Event()
        threading.Thread(target=self._run, args=(load, watched), daemon=True, name="texture-reload").start()

    def _run(self, load, watched: _Watched) -> None:
        try:
            self.texture = load(watched, self.changed)
        except Exception as error:  # noqa: BLE001 - whatever the file is, the demo keeps its texture
            reason = str(error).splitlines()[0] if str(error) else type(error).__name__
            self.error = f"cannot reload {self.changed.name}: {reason}"
        finally:
            self.done.set()


class TextureWatcher:
    """Watches the files of the textures given by path; :meth:`poll` returns the reloaded ones."""

    def __init__(self, sources: dict[int, tuple[Path, object]]):
        """``sources``: the demo's texture index → (the file it was loaded from, the Texture)."""
        self.watched: list[_Watched] = []
        for index, (path, texture) in sources.items():
            source = Path(texture.source) if getattr(texture, "source", "") else None
            if source is not None and (not source.is_file() or source.resolve() == Path(path).resolve()):
                source = None
            files = [Path(path)] + ([source] if source else [])
            keys = {f: _look(f)[0] for f in files}
            self.watched.append(_Watched(index, Path(path), source, keys, dict(keys)))
        self.errors: list[str] = []

    def poll(self) -> list[tuple[int, object]]:
        """(index, new Texture) for each texture whose file or source changed and loaded; problems go to
        ``errors`` (one line each) while they last, the texture last loaded staying."""
        reloaded = []
        self.errors = []
        for watched in self.watched:
            if watched.loading is not None:
                if not watched.loading.done.is_set():
                    if watched.error:
                        self.errors.append(watched.error)
                    continue
                load, watched.loading = watched.loading, None
                if load.texture is None:
                    watched.failed, watched.error = load.seen, load.error
                else:
                    watched.keys, watched.failed, watched.error = load.seen, None, ""
                    reloaded.append((watched.index, load.texture))
            changed, missing = None, None
            for path in watched.keys:
                key, problem = _look(path)
                stable = key == watched.seen[path]
                watched.seen[path] = key
                if key is None:
                    if stable and path == watched.path:  # gone for a whole poll: not an editor's rename
                        missing = f"cannot reload {path.name}: {problem}"  # (a source image may go: it is a copy)
                elif stable and key != watched.keys[path]:
                    changed = path
            if missing is not None:
                watched.failed, watched.error = None, missing
            elif changed is not None and watched.failed != watched.seen:
                watched.loading = _Load(self._load, watched, changed)
            elif changed is None and missing is None and watched.keys == watched.seen:
                watched.error = ""  # back as it was loaded
            if watched.error:
                self.errors.append(watched.error)
        return reloaded

    @staticmethod
    def _load(watched: _Watched, changed: Path):
        from ultraglide.textures.library import resolve_texture

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a plain image is authored with defaults, as at start-up
            if changed == watched.source:
                from ultraglide.textures.authoring import AuthoringOptions, author_image

                texture = resolve_texture(str(watched.path))
                names = {f.name for f in dataclasses.fields(AuthoringOptions)}
                recorded = texture.authoring
                options = {key: tuple(value) if isinstance(value, list) else value
                           for key, value in recorded.items() if key in names
                           and not (key in ("black", "white") and recorded.get("auto_levels") is not None)}
                return author_image(watched.source, AuthoringOptions(**options), name=texture.name)
            return resolve_texture(str(watched.path))
