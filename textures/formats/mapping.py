"""How a haptic texture's texel becomes a friction ratio: stated and chosen here, in one place.

A glTF ``MPEG_haptic_material`` ``friction`` texture stores "coefficients of friction" as image texels; the
standard does not say how a texel scales to a physical quantity. ultraglide reads a texel's first channel
(gray, or red in a colour image), normalised to 0..1 (an 8-bit texel over 255, a 16-bit one over 65535), and
maps it linearly onto a friction ratio range::

    ratio = low + (high - low) * texel            (texel = 1 - texel first when inverted)

The default, ``low = 0``, ``high = 1``, not inverted, is ultraglide's own file's rule: white is the plate at
rest (ratio 1, full friction), black the most the plate can reduce; a texture written by ultraglide reads back
unchanged. ``--ratio-range LOW,HIGH`` and ``--invert`` choose another (``texture import``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ultraglide.textures.errors import TextureError


@dataclass(frozen=True)
class TexelMapping:
    """The linear map from a texel (0..1) to a friction ratio: ``low + (high - low) * texel``.

    Parameters
    ----------
    low, high : float
        Friction ratios (0..1, ``low <= high``) a black and a white texel give (swapped when ``invert``).
    invert : bool
        Black is at rest (the ratio ``high``) and white the slipperiest.

    Examples
    --------
    >>> TexelMapping(0.2, 1.0).ratio(np.array([0.0, 0.5, 1.0])).tolist()
    [0.20000000298023224, 0.6000000238418579, 1.0]
    """

    low: float = 0.0
    high: float = 1.0
    invert: bool = False

    def __post_init__(self) -> None:
        ok = all(isinstance(v, int | float) and math.isfinite(v) for v in (self.low, self.high))
        if not (ok and 0.0 <= self.low <= self.high <= 1.0):
            raise TextureError(f"a texel mapping's friction ratios must satisfy 0 <= low <= high <= 1, got "
                               f"{self.low} {self.high}")

    @property
    def identity(self) -> bool:
        """Whether a texel is the ratio itself (ultraglide's own rule).

        Examples
        --------
        >>> TexelMapping().identity, TexelMapping(0.2, 1.0).identity, TexelMapping(invert=True).identity
        (True, False, False)
        """
        return self.low == 0.0 and self.high == 1.0 and not self.invert

    def ratio(self, texels: np.ndarray) -> np.ndarray:
        """Friction ratios (float32) of ``texels`` (0..1); in place when they are float32 already.

        Parameters
        ----------
        texels : numpy.ndarray
            Texels, 0..1.

        Returns
        -------
        numpy.ndarray
            Friction ratios, float32.

        Examples
        --------
        Inverted over 0.2..1: black (0) at rest, white (1) at 0.2:

        >>> import numpy as np
        >>> [round(float(v), 6) for v in TexelMapping(0.2, 1.0, invert=True).ratio(np.array([0.0, 1.0]))]
        [1.0, 0.2]
        """
        values = np.asarray(texels, dtype=np.float32)
        if self.identity:
            return values
        if self.invert:
            np.subtract(np.float32(1.0), values, out=values)
        values *= np.float32(self.high - self.low)
        values += np.float32(self.low)
        return values

    def texel(self, ratios: np.ndarray) -> np.ndarray:
        """The texels (0..1, float32) that map to ``ratios``: the inverse of :meth:`ratio`, clipped.

        Parameters
        ----------
        ratios : numpy.ndarray
            Friction ratios.

        Returns
        -------
        numpy.ndarray
            Texels, 0..1 (float32).

        Examples
        --------
        The inverse of :meth:`ratio`; a ratio below ``low`` clips to black:

        >>> import numpy as np
        >>> mapping = TexelMapping(0.2, 1.0)
        >>> [round(float(v), 6) for v in mapping.texel(mapping.ratio(np.array([0.0, 0.25, 1.0])))]
        [0.0, 0.25, 1.0]
        >>> mapping.texel(np.array([0.1])).tolist()
        [0.0]
        """
        values = np.asarray(ratios, dtype=np.float32)
        span = self.high - self.low
        texels = np.zeros_like(values) if span == 0 else (values - np.float32(self.low)) / np.float32(span)
        np.clip(texels, 0.0, 1.0, out=texels)
        return 1.0 - texels if self.invert else texels

    def describe(self) -> str:
        """The rule in words, as ``texture import`` prints it.

        Returns
        -------
        str

        Examples
        --------
        >>> TexelMapping(0.2, 1.0, invert=True).describe()
        'friction ratio = 0.2 + 0.8 × (1 - texel)'
        """
        rule = "1 - texel" if self.invert else "texel"
        if self.identity:
            return "friction ratio = texel (white = 1, the plate at rest; black = 0)"
        return f"friction ratio = {self.low:g} + {self.high - self.low:g} × ({rule})"
