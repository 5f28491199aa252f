"""Seams of tiling textures: measuring the jump where a tile meets the next, and removing it.

A tiling texture repeats: its last column is followed by its first, its last row by its first.
The *seam jump* is the step across that join; the *interior step* is the step between
neighbouring pixels inside. A texture tiles seamlessly when no seam step is larger than the
largest interior step (what :func:`measure_seams` reports and the tests check), and a finger
feels a seam when the typical (rms) seam step is well above the typical interior step
(:attr:`SeamReport.visible`, the authoring warning).

:func:`make_seamless` turns any image into a tile, by one of two methods:

- ``crossfade`` (the default): a band at each end is cross-faded into the opposite end, so the
  tile is shorter by the band and the features keep their size and look; inside the band, the
  picture is a blend of two parts of the image (less contrast where they are unrelated).
- ``mirror``: the image, its mirror image to the right, and both mirrored below: a tile twice as
  wide and high, exactly seamless, with a visible symmetry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ultraglide.textures.errors import TextureError

METHODS = ("crossfade", "mirror")
DEFAULT_BAND = 0.125
VISIBLE_RATIO = 2.0  # a seam whose rms step is twice the interior's stands out to eye and finger


@dataclass(frozen=True)
class SeamReport:
    """Steps across the tile's seams and between neighbours inside, in the texture's value units.

    Attributes
    ----------
    seam_max, interior_max : float
        The largest step across the seams and between neighbours inside.
    seam_rms, interior_rms : float
        Their RMS.

    Examples
    --------
    >>> report = SeamReport(seam_max=1.0, interior_max=0.1, seam_rms=1.0, interior_rms=0.1)
    >>> round(report.ratio, 6), report.seamless, report.visible
    (10.0, False, True)
    """

    seam_max: float  # largest step across either seam
    interior_max: float  # largest step between neighbours inside
    seam_rms: float
    interior_rms: float

    @property
    def ratio(self) -> float:
        """Typical seam step over typical interior step (about 1 for a seamless tile).

        Examples
        --------
        >>> SeamReport(seam_max=0.4, interior_max=0.2, seam_rms=0.3, interior_rms=0.15).ratio      # 0.3 / 0.15
        2.0
        """
        if self.interior_rms > 0:
            return self.seam_rms / self.interior_rms
        return 1.0 if self.seam_rms == 0 else float("inf")

    @property
    def seamless(self) -> bool:
        """No step across a seam is larger than the largest step inside (a little float slack).

        Examples
        --------
        >>> SeamReport(seam_max=0.2, interior_max=0.2, seam_rms=0.1, interior_rms=0.1).seamless
        True
        """
        return self.seam_max <= self.interior_max + 1e-6

    @property
    def visible(self) -> bool:
        """The seam stands out: its typical step is over twice the typical interior step.

        Examples
        --------
        >>> SeamReport(seam_max=0.2, interior_max=0.2, seam_rms=0.1, interior_rms=0.1).visible    # ratio 1: not over 2
        False
        """
        return self.ratio > VISIBLE_RATIO and self.seam_max > self.interior_max + 1e-6


def measure_seams(values: np.ndarray) -> SeamReport:
    """Seam and interior steps of a map that tiles (rows × cols; each axis with 2 pixels or more is measured).

    Parameters
    ----------
    values : numpy.ndarray, shape (rows, cols)

    Returns
    -------
    SeamReport
        The largest and RMS steps across the tile's edges and inside it; ``visible`` when a finger would feel
        the seam.

    Examples
    --------
    >>> import numpy as np
    >>> ramp = np.tile(np.linspace(0.0, 1.0, 8), (4, 1))                 # 1 → 0 across the edge
    >>> report = measure_seams(ramp)
    >>> report.seam_max, round(report.interior_max, 4), report.visible      # 1 against 1/7
    (1.0, 0.1429, True)
    """
    values = np.asarray(values, dtype=np.float64)
    seam, interior = [], []
    for axis in (0, 1):
        if values.shape[axis] < 2:
            continue
        interior.append(np.abs(np.diff(values, axis=axis)).ravel())
        first, last = np.take(values, 0, axis=axis), np.take(values, -1, axis=axis)
        seam.append(np.abs(first - last).ravel())
    if not seam:
        return SeamReport(0.0, 0.0, 0.0, 0.0)
    seam_steps, interior_steps = np.concatenate(seam), np.concatenate(interior)
    return SeamReport(float(seam_steps.max()), float(interior_steps.max()),
                      float(np.sqrt(np.mean(seam_steps ** 2))), float(np.sqrt(np.mean(interior_steps ** 2))))


def _crossfade_axis(values: np.ndarray, band: int, axis: int) -> np.ndarray:
    """Cross-fade the last ``band`` pixels along ``axis`` into the first ones; ``band`` pixels shorter."""
    if band <= 0:
        return values
    moved = np.moveaxis(values, axis, 0)
    keep = moved.shape[0] - band
    # weight of the image's own start: 0 at the seam (where the cut-off end continues the tile's
    # last pixel), rising smoothly to 1 at the band's inner edge
    t = (np.arange(band) + 0.5) / band
    weight = (0.5 - 0.5 * np.cos(np.pi * t))[:, None]
    out = moved[:keep].copy()
    out[:band] = weight * moved[:band] + (1 - weight) * moved[keep:]
    return np.moveaxis(out, 0, axis)


def make_seamless(values: np.ndarray, method: str = "crossfade", band: float = DEFAULT_BAND) -> np.ndarray:
    """A version of ``values`` (rows × cols) that tiles without a seam; see the module docstring.

    ``band`` is the cross-fade band as a fraction of each side (0 < band ≤ 0.5); ``mirror`` ignores it.

    Parameters
    ----------
    values : numpy.ndarray, shape (rows, cols)
    method : {"crossfade", "mirror"}
        Cross-fade the edges into each other, or mirror the map (doubling each side).
    band : float
        The cross-fade band as a fraction of each side, 0 < band <= 0.5.

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    TextureError
        An unknown method or a band out of range.

    Examples
    --------
    >>> import numpy as np
    >>> ramp = np.tile(np.linspace(0.0, 1.0, 8), (4, 1))                 # 1 → 0 across the edge
    >>> measure_seams(make_seamless(ramp)).visible, make_seamless(ramp, "mirror").shape
    (False, (8, 16))
    """
    values = np.asarray(values, dtype=np.float64)
    if method not in METHODS:
        raise TextureError(f"the seamless method must be one of {', '.join(METHODS)}, got {method!r}")
    if method == "mirror":
        top = np.hstack([values, values[:, ::-1]])
        return np.vstack([top, top[::-1]])
    if not (np.isfinite(band) and 0 < band <= 0.5):
        raise TextureError(f"the seam band is a fraction of the side in (0, 0.5], got {band}")
    rows, cols = values.shape
    if min(rows, cols) < 4:
        raise TextureError(f"a {cols}×{rows} image is too small to cross-fade into a tile; use --seamless mirror")
    values = _crossfade_axis(values, max(1, round(band * cols)), axis=1)
    return _crossfade_axis(values, max(1, round(band * rows)), axis=0)
