"""``demo --watch``: notice when a texture's file or its source image changes, and load it again.

The demo's loop calls :meth:`TextureWatcher.poll` from its event wait's timeout (every 200 ms), so
watching costs a few ``stat`` calls a poll and no thread. A file counts as changed when its
(inode, size, mtime) differs from what was loaded and has stayed the same for one poll, so neither an
in-place rewrite caught half-written nor an editor's rename is loaded before it is whole; a file
that fails to load is tried again at the next poll.

A texture file loads as it is; a plain image is authored with the defaults (as the demo does at
start-up); when the source image a texture file was authored from changes, the texture is authored
again from it with the options recorded in the file (the file itself is not rewritten).
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

POLL_S = 0.2


def _key(path: Path) -> tuple[int, int, int] | None:
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_ino, info.st_size, info.st_mtime_ns


@dataclass
class _Watched:
    index: int  # in the demo's list of textures
    path: Path  # the file the texture came from
    source: Path | None  # the image it was authored from, when that is another file that exists
    keys: dict  # path → the key last loaded
    seen: dict  # path → the key seen at the last poll


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
            keys = {f: _key(f) for f in files}
            self.watched.append(_Watched(index, Path(path), source, keys, dict(keys)))
        self.errors: list[str] = []

    def poll(self) -> list[tuple[int, object]]:
        """(index, new Texture) for each texture whose file or source changed and loaded; problems go
        to ``errors`` (one line each) and are retried."""
        reloaded = []
        self.errors = []
        for watched in self.watched:
            changed = None
            for path in watched.keys:
                key = _key(path)
                stable = key is not None and key == watched.seen[path]
                watched.seen[path] = key
                if stable and key != watched.keys[path]:
                    changed = path
            if changed is None:
                continue
            try:
                texture = self._load(watched, changed)
            except Exception as error:  # noqa: BLE001 - an editor's half-saved file: say so, try again later
                reason = str(error).splitlines()[0] if str(error) else type(error).__name__
                self.errors.append(f"cannot reload {changed.name}: {reason}")
                continue
            for path in watched.keys:
                watched.keys[path] = watched.seen[path]
            reloaded.append((watched.index, texture))
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
