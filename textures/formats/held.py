"""A decoded friction map at the resolution a texture is held at, quickly: Pillow's box filter as sparse products.

:func:`ultraglide.textures.fileformat.held_size` says how many pixels a texture is held in (at most 20 per mm,
at most 16 M in all); a larger map is averaged down with Pillow's ``BOX`` resampling, as a texture file is
(:func:`ultraglide.textures.fileformat.load_texture`). Pillow does that on 32-bit integers in two passes,
rounding to whole codes after each, and the result is then converted to float32; here the same weights
(:func:`box_weights`: each held pixel the mean of a run of consecutive file pixels) are summed in one compiled
pass over the codes into float32 values (no rounding to codes), instead of Pillow's resampling and a conversion.
"""

from __future__ import annotations

import numpy as np


def box_weights(n_in: int, n_out: int):
    """The sparse matrix (``n_out`` × ``n_in``, weights summing to 1 a row) of Pillow's ``BOX`` resampling from
    ``n_in`` samples to ``n_out`` (``n_out`` <= ``n_in``).

    Pillow's box filter (``precompute_coeffs`` in its ``Resample.c``) weighs equally every input sample whose
    centre lies within the output's span (scale = ``n_in`` / ``n_out``; an input at centre ``c`` counts for the
    output centred at ``C`` when −0.5 < (c − C) / scale <= 0.5), and divides by their number: the mean of the
    samples an output covers, not an area-weighted one. The same weights here keep a map read from a glTF scene
    equal (within the rounding Pillow does, half a code a pass) to the same map read from a texture file.

    Parameters
    ----------
    n_in, n_out : int
        Samples in and out (1 <= ``n_out`` <= ``n_in``).

    Returns
    -------
    scipy.sparse.csr_matrix

    Examples
    --------
    >>> box_weights(4, 2).toarray().tolist()
    [[0.5, 0.5, 0.0, 0.0], [0.0, 0.0, 0.5, 0.5]]
    """
    from scipy import sparse

    if not 1 <= n_out <= n_in:
        raise ValueError(f"a box filter shrinks: {n_in} samples into {n_out}")
    scale = float(np.float32(n_in)) / n_out  # Pillow: (double)(in1 - in0) / outSize, in1 a float
    support = 0.5 * scale
    centre = (np.arange(n_out) + 0.5) * scale
    first = np.maximum((centre - support + 0.5).astype(np.int64), 0)  # C's (int) truncates: all >= 0 here
    last = np.minimum((centre + support + 0.5).astype(np.int64), n_in)
    taps = int(np.max(last - first))
    cols = first[:, None] + np.arange(taps)[None, :]
    x = (cols - centre[:, None] + 0.5) / scale
    weights = ((x > -0.5) & (x <= 0.5) & (cols < last[:, None])).astype(np.float64)
    weights /= weights.sum(axis=1, keepdims=True)
    keep = weights > 0
    rows = np.broadcast_to(np.arange(n_out)[:, None], cols.shape)
    return sparse.csr_matrix((weights[keep], (rows[keep], cols[keep])), shape=(n_out, n_in))


def _ranges(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray] | None:
    """Where each output's inputs start and how many there are, when Pillow's box weights (:func:`box_weights`)
    average runs of consecutive inputs that follow one another and cover every input once (a shrink always does,
    but for ties the floating point may break); None otherwise."""
    weights = box_weights(n_in, n_out)
    counts = np.diff(weights.indptr)
    if np.any(counts == 0):
        return None
    starts = weights.indices[weights.indptr[:-1]]
    along = np.arange(weights.nnz) - np.repeat(weights.indptr[:-1], counts)
    if not (np.array_equal(weights.indices, np.repeat(starts, counts) + along) and starts[0] == 0
            and np.array_equal(starts[1:], (starts + counts)[:-1]) and starts[-1] + counts[-1] == n_in
            and np.allclose(weights.data, np.repeat(1.0 / counts, counts), rtol=0, atol=1e-12)):
        return None
    return starts.astype(np.intp), counts


def held_map(codes: np.ndarray, size: tuple[int, int], full_scale: float) -> np.ndarray:
    """The map of ``codes`` (rows × cols, integers 0..``full_scale``) as float32 values 0..1 at ``size``
    (held cols, held rows), box-filtered as Pillow's ``BOX`` resampling does when smaller.

    Each held pixel is the mean of the run of rows and the run of columns Pillow's weights give it, summed in
    one compiled pass (:func:`ultraglide.textures.formats.kernels.box_runs`). Should the weights not be such
    runs (a tie the floating point breaks), they are applied as sparse products.

    Parameters
    ----------
    codes : numpy.ndarray
        The decoded texels (2-D, an integer type).
    size : (int, int)
        Columns and rows to hold the map in (each at most the codes' own).
    full_scale : float
        The code that is 1 (255 for 8-bit texels, 65535 for 16-bit).

    Returns
    -------
    numpy.ndarray
        float32, ``size[1]`` × ``size[0]``, within 0..1.

    Examples
    --------
    >>> held_map(np.array([[0, 65535], [65535, 65535]], np.uint16), (1, 1), 65535.0).tolist()
    [[0.75]]
    """
    rows, cols = codes.shape
    held_cols, held_rows = size
    across = _ranges(cols, held_cols) if held_cols != cols else (np.arange(cols, dtype=np.intp), np.ones(cols, int))
    down = _ranges(rows, held_rows) if held_rows != rows else (np.arange(rows, dtype=np.intp), np.ones(rows, int))
    if across is None or down is None:
        values = (box_weights(rows, held_rows) @ codes.astype(np.float64)) @ box_weights(cols, held_cols).T
        values = np.ascontiguousarray(values, dtype=np.float32)
        values *= np.float32(1.0 / full_scale)
        np.clip(values, 0.0, 1.0, out=values)
    else:  # held as it is, too: the conversion, scale and clip in that one pass
        from ultraglide.textures.formats.kernels import box_runs

        if not codes.dtype.isnative or codes.dtype not in (np.uint8, np.uint16, np.int32):
            codes = codes.astype(np.int32)
        values = np.empty((held_rows, held_cols), dtype=np.float32)
        box_runs(codes, down[0], down[1].astype(np.intp), across[0], across[1].astype(np.intp),
                 float(full_scale), values)
    return values
