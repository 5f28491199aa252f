"""The plate-driver firmware: its board ports, their cross build and QEMU runs (the C sources beside)."""
