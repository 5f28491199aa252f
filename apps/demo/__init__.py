"""``ultraglide demo``, in rooms: ``options`` (set-up), ``scenes`` (gallery, one texture, widgets), ``layout``,
``input`` (mouse, touch, keys), ``painter`` and ``draw`` (drawing), ``status`` (the status line's words),
``app`` (the loop), ``link`` (the engine), ``record``, ``watch`` and ``wait``."""

import os

os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # before pygame is imported: no banner
# The window's pixels go to X directly (shared memory). Otherwise SDL may put them through OpenGL,
# which without a GPU is Mesa's llvmpipe: two software-rendering threads costing a third of a core.
os.environ.setdefault("SDL_FRAMEBUFFER_ACCELERATION", "0")
