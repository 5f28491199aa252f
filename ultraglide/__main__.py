"""``python -m ultraglide``: the same as the ``ultraglide`` command."""

from ultraglide.apps.cli import console

if __name__ == "__main__":
    raise SystemExit(console())
