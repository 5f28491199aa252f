"""A texture file's size limit, in a module of its own: the command line's option types read it without numpy."""

MAX_PIXELS = 100_000_000  # pixels a texture file may hold (float32: 400 MB once read)
