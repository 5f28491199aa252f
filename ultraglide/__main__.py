"""``python -m ultraglide``: the same as the ``ultraglide`` command."""

from ultraglide.apps.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
