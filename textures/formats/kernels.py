"""Compiled kernel (numba) for reading haptic formats: a decoded map averaged into the pixels it is held in.

Compiled code is cached on disk beside this file (numba ``cache=True``); ``python -m ultraglide.compile_kernels``
(run by ``./run`` after installing) compiles it with the types :func:`warm_up` passes.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def box_runs(codes, row_start, row_count, col_start, col_count, top, out):
    """A decoded map averaged into the pixels it is held in, as fractions of full scale.

    Each ``out[j, k]`` (float32, clipped to 0..1) is the mean of ``codes`` over rows ``row_start[j]`` onward
    (``row_count[j]`` of them) and columns ``col_start[k]`` onward (``col_count[k]``), over ``top``: the run of
    rows summed into one row, then each run of columns of it, in one pass over the codes (float32 sums: exact
    for up to 256 16-bit codes, within a relative 1e-7 beyond).

    Parameters
    ----------
    codes : numpy.ndarray of uint8, uint16 or int32, shape (rows, cols)
        The decoded texels.
    row_start, row_count, col_start, col_count : numpy.ndarray of intp
        Each held pixel's first row and column, and how many of each it averages.
    top : float
        The code of full scale (255 for 8 bits).
    out : numpy.ndarray of float32, shape (held rows, held cols)
        Filled with the means over ``top``, 0..1.

    Returns
    -------
    None

    Examples
    --------
    A 2 × 4 map of 8-bit codes held in one row of two pixels, each the mean of a 2 × 2 box:

    >>> import numpy as np
    >>> codes = np.array([[0, 255, 51, 51], [255, 0, 102, 102]], dtype=np.uint8)
    >>> out = np.empty((1, 2), dtype=np.float32)
    >>> box_runs(codes, np.array([0]), np.array([2]), np.array([0, 2]), np.array([2, 2]), 255.0, out)
    >>> out.astype(float).round(6).tolist()
    [[0.5, 0.3]]
    """
    held_rows, held_cols = out.shape
    cols = codes.shape[1]
    row = np.empty(cols, dtype=np.float32)
    for j in range(held_rows):
        r0, nr = row_start[j], row_count[j]
        for c in range(cols):
            row[c] = codes[r0, c]
        for a in range(1, nr):
            for c in range(cols):
                row[c] += codes[r0 + a, c]
        scale = np.float32(1.0 / (nr * top))
        for k in range(held_cols):
            c0, nc = col_start[k], col_count[k]
            total = row[c0]
            for b in range(1, nc):
                total += row[c0 + b]
            value = total * (scale / np.float32(nc))
            out[j, k] = min(max(value, np.float32(0.0)), np.float32(1.0))


def warm_up() -> None:
    """Compile (or load from numba's cache) :func:`box_runs` for the texel types a decoded map has.

    8-bit, 16-bit and 32-bit integers.

    Returns
    -------
    None

    Examples
    --------
    >>> warm_up()
    >>> len(box_runs.signatures) >= 3
    True
    """
    runs = np.zeros(1, dtype=np.intp), np.ones(1, dtype=np.intp)
    for kind in (np.uint8, np.uint16, np.int32):
        box_runs(np.zeros((1, 1), dtype=kind), *runs, *runs, 1.0, np.empty((1, 1), dtype=np.float32))
