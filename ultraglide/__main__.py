"""``python -m ultraglide``: the same as the ``ultraglide`` command."""

from ultraglide.apps.cli.main import console

if __name__ == "__main__":
    raise SystemExit(console())
