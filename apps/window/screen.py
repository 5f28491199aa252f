"""The screen a window opens on: whether there is one, that it answered, and its scale when its size is not given."""

from __future__ import annotations

import os

DEFAULT_MM_PER_PX = 25.4 / 96  # when the screen's size is not given: a 96 dpi screen


def display_available() -> bool:
    """Whether SDL has a display to open a window on (an X or Wayland display, or a video driver named)."""
    driver = os.environ.get("SDL_VIDEODRIVER", "")
    return bool(driver or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


INVISIBLE_DRIVERS = ("offscreen", "dummy")  # SDL draws, and nobody sees it


def init_display(pygame) -> None:
    """Start pygame's display on the screen the environment names, or raise ``pygame.error`` saying why not.

    Left to itself, SDL tries every video driver it has, and when the display named does not answer (a wrong
    ``DISPLAY``, an X server down, an Xvfb resetting as its last client left) it ends, without a word, on its
    ``offscreen`` driver: a window would open there and wait for a person who cannot see it. So unless
    ``SDL_VIDEODRIVER`` chooses, SDL is asked for the driver of the display named (``WAYLAND_DISPLAY``: Wayland,
    then X11 where ``DISPLAY`` is set too; ``DISPLAY``: X11), and an invisible driver nobody asked for is refused.

    Parameters
    ----------
    pygame : module
        The ``pygame`` module.

    Raises
    ------
    pygame.error
        The display did not answer, in words; the display is left shut.

    Examples
    --------
    >>> import os, pygame
    >>> saved = os.environ.get("SDL_VIDEODRIVER")
    >>> os.environ["SDL_VIDEODRIVER"] = "dummy"   # an invisible display, asked for
    >>> init_display(pygame); pygame.display.get_driver()
    'dummy'
    >>> pygame.display.quit()
    >>> _ = os.environ.pop("SDL_VIDEODRIVER") if saved is None else os.environ.update(SDL_VIDEODRIVER=saved)
    """
    original = os.environ.get("SDL_VIDEODRIVER")
    asked = original or ""
    x11, wayland = os.environ.get("DISPLAY"), os.environ.get("WAYLAND_DISPLAY")
    named = wayland or x11
    choice = asked or ",".join(name for name, given in (("wayland", wayland), ("x11", x11)) if given)
    where = f"the display {named} did not answer" if named else "no display answered"
    try:
        if choice != asked:  # read once, when the display starts; the engine's process started later inherits none
            os.environ["SDL_VIDEODRIVER"] = choice
        try:
            pygame.display.init()
        except pygame.error as error:
            raise pygame.error(f"{where}, SDL says: {error}; check DISPLAY and that its server runs") from None
    finally:
        if choice != asked:
            if original is None:
                del os.environ["SDL_VIDEODRIVER"]
            else:
                os.environ["SDL_VIDEODRIVER"] = original
    driver = pygame.display.get_driver()
    if driver in INVISIBLE_DRIVERS and driver not in [name.strip() for name in choice.split(",")]:
        pygame.display.quit()
        raise pygame.error(f"{where}, and SDL would have drawn where nobody sees it (its {driver} driver); check "
                           "DISPLAY and that its server runs")
