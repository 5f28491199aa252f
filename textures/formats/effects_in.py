"""Designers' effect files as ultraglide temporal effects: AHAP (``.ahap``), Meta (``.haptic``), MPEG (``.hjif``),
Interhaptics (``.haps``, its vibration block).

:func:`load_designer_effects` reads one (a regular file, at most a few MB, JSON of bounded depth), turns it into a
:class:`~ultraglide.textures.formats.timeline.Timeline` and from that into bindings; what cannot be rendered on a
friction display is said in a warning per kind of loss, each naming the file.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from ultraglide.textures.errors import TextureError

from ultraglide.inputs import parse_json, read_input

SUFFIXES = {".ahap": "AHAP file", ".haptic": "Meta .haptic file", ".hjif": "MPEG-I haptics file",
            ".haps": "Interhaptics .haps file"}


def load_designer_effects(path, full_depth: float = 1.0) -> tuple:
    """Bindings (played from when the finger lands) from an ``.ahap``, ``.haptic``, ``.hjif`` or ``.haps`` file.

    Parameters
    ----------
    path : str or path-like
        The file; its suffix says its format.
    full_depth : float
        The friction drop an intensity (amplitude) of 1 gives, 0..1.

    Returns
    -------
    tuple of Binding
        Empty when nothing in the file renders (each loss is warned).

    Raises
    ------
    TextureError
        One line: an unknown suffix, not JSON, a field missing or out of range, more events than effects hold.

    Examples
    --------
    >>> import json, pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "tap.ahap"
    >>> _ = path.write_text(json.dumps({"Version": 1.0, "Pattern": [{"Event": {"Time": 0.0,
    ...     "EventType": "HapticTransient", "EventParameters": [{"ParameterID": "HapticIntensity",
    ...                                                           "ParameterValue": 0.8}]}}]}))
    >>> bindings = load_designer_effects(path)
    >>> len(bindings)
    1
    """
    from ultraglide.textures.formats import ahap, haps, hjif

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise TextureError(f"{path}: effects are read from .json (ultraglide's), .ahap, .haptic, .hjif or .haps "
                           "files")
    what = SUFFIXES[suffix]
    document = parse_json(read_input(path, what, TextureError), str(path), TextureError, what=what)
    reader = {".ahap": ahap.read_ahap, ".haptic": ahap.read_meta_haptic, ".hjif": hjif.read_hjif,
              ".haps": haps.read_haps_effects}[suffix]
    timeline = reader(document, str(path), full_depth)
    for note in timeline.notes:
        warnings.warn(f"{path}: {note}", stacklevel=2)
    bindings = timeline.bindings(path.stem)
    if not bindings:
        warnings.warn(f"{path}: nothing in it renders on a friction display; no effects", stacklevel=2)
    return bindings
