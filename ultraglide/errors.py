"""The root of every error ultraglide raises for a person to act on, and the one line that describes one.

``except ultraglide.UltraglideError`` catches anything the library refused: a texture, a model, a
setting, a device, a file. Each package's errors derive from it and keep their older bases
(``ValueError`` for bad values, ``RuntimeError`` for devices), as python-soundfile added
``SoundFileError`` under its old bases, so callers that caught those still do.

This module imports nothing of ours: every package, ``devices`` and ``textures`` included, may import it.
"""

from __future__ import annotations

import errno


class UltraglideError(Exception):
    """Anything ultraglide refused; the message is one line that says what is wrong and what to do.

    Each package's errors derive from it and keep their older bases (``ValueError`` for bad values,
    ``RuntimeError`` for devices): catch this one to catch them all. Raised with one argument, the message: one
    line, what is wrong and what to do.

    Examples
    --------
    >>> import ultraglide
    >>> try:
    ...     ultraglide.load_profile("no-such-plate")
    ... except UltraglideError as error:
    ...     print(type(error).__name__, "|", error)
    ProfileError | no plate profile file or bundled profile 'no-such-plate'; bundled: audio-generic, sim-plate
    """


_NO_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)


# what a library says when the memory it asked for was refused, under whatever error it raises then (the loader's
# dlopen through llvmlite's "literally cannot be found", numpy's MemoryError, the C library's ENOMEM)
_NO_MEMORY_WORDS = ("failed to map segment from shared object", "cannot allocate memory", "out of memory",
                    "unable to allocate")


def out_of_memory(error: BaseException) -> str | None:
    """One line when ``error`` (or what it was raised from) is memory refused: what was being done, how much where
    it is known, this process's limit and what to do; None for any other error.

    Parameters
    ----------
    error : BaseException
        The error, with its ``__cause__`` and ``__context__`` chain.

    Returns
    -------
    str or None
        E.g. ``"out of memory: unable to allocate 1.2 GiB for an array ...; this process may use at most 293 MiB
        of address space (ulimit -v 300000): raise the limit or free memory"``.

    Examples
    --------
    >>> out_of_memory(MemoryError("Unable to allocate 1.00 GiB for an array with shape (134217728,)"))
    ... # doctest: +ELLIPSIS
    'out of memory: Unable to allocate 1.00 GiB for an array with shape (134217728,)...'
    >>> out_of_memory(ValueError("a bad value")) is None
    True
    """
    seen, chain, found = set(), error, None
    while chain is not None and id(chain) not in seen and found is None:
        seen.add(id(chain))
        text = str(chain).splitlines()[0] if str(chain) else ""
        if isinstance(chain, MemoryError) or (isinstance(chain, OSError) and chain.errno == errno.ENOMEM) or any(
                words in text.lower() for words in _NO_MEMORY_WORDS):
            found = chain
        chain = chain.__cause__ or (None if chain.__suppress_context__ else chain.__context__)
    if found is None:
        return None
    text = str(found).splitlines()[0] if str(found) else "memory refused"
    if "shared object" in text:
        text = f"a library could not be loaded ({text.strip().rstrip('.')})"
    return f"out of memory: {text.strip().rstrip('.')}; {_memory_limit()}"


def _memory_limit() -> str:
    """This process's address-space limit, and what to do, in words."""
    try:
        import resource

        limit, unlimited = resource.getrlimit(resource.RLIMIT_AS)[0], resource.RLIM_INFINITY
    except (ImportError, OSError, ValueError):  # no resource module (Windows): no limit to name
        limit = unlimited = -1
    if limit == unlimited or limit < 0:
        return "free memory (close other programs) or run with less at once"
    return (f"this process may use at most {limit / 2 ** 20:,.0f} MiB of address space (ulimit -v {limit // 1024}): "
            "raise the limit or free memory")


def describe(error: BaseException) -> str:
    """One line for an error a person can act on: OSErrors name the file and the reason (a full disk says that
    nothing was saved); memory refused says so (:func:`out_of_memory`, whatever a library raised); other errors
    give their message's first line. Shared by the command and the engine process, which reports its errors to
    the app as text.

    Parameters
    ----------
    error : BaseException

    Returns
    -------
    str
        One line.

    Examples
    --------
    >>> describe(FileNotFoundError(2, "No such file or directory", "wood.png"))
    'wood.png: no such file or directory'
    >>> describe(ValueError("a first line\\nand a second"))
    'a first line'
    """
    memory = out_of_memory(error)
    if memory is not None:
        return memory
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        advice = "; nothing was saved: free some space or write elsewhere" if error.errno in _NO_ROOM else ""
        return f"{where}{error.strerror.lower()}{advice}"
    return str(error).splitlines()[0] if str(error) else type(error).__name__
