"""Cross-building the firmware's board images: ``ultraglide firmware build`` and ``plate-sim --board NAME``.

The boards: ``netduinoplus2`` (STM32F405; images ``hardware``, ``qemu``, ``bench``) and ``mps2-an386`` (ARM's
MPS2 with the AN386 image, CMSDK peripherals; its ``qemu`` image only). A board port lives in
``devices/firmware/ports/BOARD/`` with a Makefile that builds each variant (``hardware``: the real
peripherals; ``qemu``: what QEMU runs, with the emulated plate standing in for the ADC; ``bench``: the budget
image). Images are built with Debian's ``gcc-arm-none-eabi`` into a cache keyed by the sources and the
compiler, so a second build is a lookup; sizes come from the linker map.

Example::

    image = build_images("netduinoplus2", ["qemu"])[0]
    image.elf_path, image.flash_bytes, image.ram_bytes
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ultraglide.devices.errors import DeviceError

FIRMWARE_DIR = Path(__file__).resolve().parent
VARIANTS = ("hardware", "qemu", "bench")
TOOLCHAIN_HINT = "install gcc-arm-none-eabi and libnewlib-arm-none-eabi (apt-get; ./run tests does)"
BUILD_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class Board:
    """A board port: its folder under ``ports/``, QEMU's machine that runs its ``qemu`` image, the variants its
    Makefile builds (the first ones by default) and its memory map (flash and RAM as [start, end) addresses)."""

    name: str
    machine: str
    variants: tuple[str, ...]
    default_variants: tuple[str, ...]
    flash: tuple[int, int]
    ram: tuple[int, int]


BOARD_INFO = {
    "netduinoplus2": Board("netduinoplus2", "netduinoplus2", ("hardware", "qemu", "bench"), ("hardware", "qemu"),
                           (0x0800_0000, 0x0810_0000), (0x2000_0000, 0x2002_0000)),
    # the AN386's SSRAM: 4 MiB at 0 holds the code, 4 MiB at 0x20000000 the data; QEMU's model only (no DAC, ADC)
    "mps2-an386": Board("mps2-an386", "mps2-an386", ("qemu", "bench"), ("qemu",),
                        (0x0000_0000, 0x0040_0000), (0x2000_0000, 0x2040_0000)),
}
BOARDS = tuple(BOARD_INFO)
FLASH_ORIGIN, FLASH_END = BOARD_INFO["netduinoplus2"].flash
RAM_ORIGIN, RAM_END = BOARD_INFO["netduinoplus2"].ram
_NOT_LOADED = (".debug", ".comment", ".ARM.attributes", ".stab")  # sections that take no memory on the board
_ZEROED = (".bss", ".stack", ".noinit", ".heap")  # RAM sections with no initial image in flash
_SECTION = re.compile(r"^(\.[\w.]+)\s+0x([0-9a-fA-F]+)\s+0x([0-9a-fA-F]+)(?:\s+load address 0x([0-9a-fA-F]+))?",
                      re.MULTILINE)


@dataclass(frozen=True)
class FirmwareImage:
    """One built image: its files and its sizes in bytes (flash: code, constants and the initial values
    of data; RAM: data, zeroed data and the reserved stack)."""

    board: str
    variant: str
    elf_path: str
    bin_path: str | None
    map_path: str
    flash_bytes: int
    ram_bytes: int
    stack_bytes: int

    def __repr__(self) -> str:
        return (f"FirmwareImage({self.board} {self.variant}: {self.elf_path}, flash {self.flash_bytes} B, "
                f"RAM {self.ram_bytes} B of which stack {self.stack_bytes} B)")

    def as_dict(self) -> dict:
        return {"board": self.board, "variant": self.variant, "elf": self.elf_path, "bin": self.bin_path,
                "map": self.map_path, "flash_bytes": self.flash_bytes, "ram_bytes": self.ram_bytes,
                "stack_bytes": self.stack_bytes}


def map_sizes(map_text: str, board: str = "netduinoplus2") -> tuple[int, int, int]:
    """Flash, RAM and stack bytes from a GNU ld map of ``board``'s image: each output section counted where it
    lives in the board's memory map (an initialised section in RAM also takes its load image's bytes in flash)."""
    (flash_origin, flash_end), (ram_origin, ram_end) = BOARD_INFO[board].flash, BOARD_INFO[board].ram
    flash = ram = stack = 0
    for name, address, size, load in _SECTION.findall(map_text):
        if name.startswith(_NOT_LOADED):
            continue  # debugging information and notes sit at address 0, which is memory on some boards
        start, length = int(address, 16), int(size, 16)
        if flash_origin <= start < flash_end:
            flash += length
        elif ram_origin <= start < ram_end:
            ram += length
            if load and flash_origin <= int(load, 16) < flash_end and name not in _ZEROED:
                flash += length
            if name == ".stack":
                stack = length
    return flash, ram, stack


def port_dir(board: str) -> Path:
    if board not in BOARDS:
        raise DeviceError(f"no board port {board!r}: the ports are {', '.join(BOARDS)}")
    return FIRMWARE_DIR / "ports" / board


def _sources_digest(board: str) -> str:
    digest = hashlib.sha256()
    for folder in (FIRMWARE_DIR / "include", FIRMWARE_DIR / "core", FIRMWARE_DIR / "ports" / "common", port_dir(board)):
        for path in sorted(folder.glob("*")) if folder.is_dir() else []:
            if path.is_file() and path.suffix in (".c", ".h", ".ld", "") and path.name != "build":
                digest.update(path.name.encode() + b"\0" + path.read_bytes())
    digest.update(_compiler_version().encode())
    return digest.hexdigest()[:16]


def _compiler_version() -> str:
    compiler = shutil.which("arm-none-eabi-gcc")
    if compiler is None or shutil.which("make") is None:
        raise DeviceError(f"the cross compiler arm-none-eabi-gcc (and make) is not installed: {TOOLCHAIN_HINT}")
    return subprocess.run([compiler, "--version"], capture_output=True, text=True, check=False).stdout


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "ultraglide" / "firmware"


def build_images(board: str = "netduinoplus2", variants=None, out_dir: str | None = None,
                 rebuild: bool = False) -> list[FirmwareImage]:
    """Build ``variants`` of ``board`` and return the images. Without ``out_dir`` the images go to the cache
    (``~/.cache/ultraglide/firmware/BOARD-DIGEST``) and are reused while the sources and compiler stay the
    same; with it they are built there. Raises :class:`DeviceError` (one line) when the toolchain is missing
    or the build fails."""
    port = port_dir(board)
    info = BOARD_INFO[board]
    variants = tuple(variants or info.default_variants)
    for variant in variants:
        if variant not in info.variants:
            raise DeviceError(f"no variant {variant!r} of {board}: its variants are {', '.join(info.variants)}")
    if out_dir is None:
        target = cache_dir() / f"{board}-{_sources_digest(board)}"
        missing = [v for v in variants if rebuild or not (target / _elf_name(board, v)).is_file()]
        if missing:
            _build_atomically(port, target, board, tuple(dict.fromkeys(tuple(variants) + tuple(missing))))
    else:
        target = Path(out_dir).resolve()
        if target.exists() and not target.is_dir():
            raise DeviceError(f"{out_dir} is not a directory: give -o a directory for the images")
        target.mkdir(parents=True, exist_ok=True)
        _refuse_what_is_not_a_build_output(target, board, variants)
        _compiler_version()
        _make(port, target, variants)
    return [_image(board, variant, target) for variant in variants]


def _refuse_what_is_not_a_build_output(target: Path, board: str, variants) -> None:
    """The build writes each variant's image, binary and map into ``target`` and its objects into
    ``target/VARIANT/``; whatever is already there under those names must be a regular file (or that folder), or
    the compiler would write into it: a named pipe would hang the build, a device node would take the image, a
    link would overwrite the file it points to. DeviceError (one line) naming the first such path."""
    def refuse(path: Path, what: str) -> None:
        raise DeviceError(f"{path} is {what}, where the build writes: move it away or give -o another directory")

    for variant in variants:
        elf = target / _elf_name(board, variant)
        for path in (elf, elf.with_suffix(".map"), elf.with_suffix(".bin")):
            if path.is_symlink():
                refuse(path, "a link")
            if path.exists() and not path.is_file():
                refuse(path, "not a regular file")
        objects = target / variant
        if objects.is_symlink() or (objects.exists() and not objects.is_dir()):
            refuse(objects, "not a directory of the build's objects")
        if objects.is_dir():
            for path in objects.iterdir():
                if path.is_symlink() or not path.is_file():
                    refuse(path, "not a regular file")


def _elf_name(board: str, variant: str) -> str:
    return f"ultraglide-{board}-{variant}.elf"


def _build_atomically(port: Path, target: Path, board: str, variants) -> None:
    """Build in a fresh folder beside the cache entry, then move each file into the entry (``os.replace``, one file
    at a time), so two builds at once (two test workers, two commands) never see each other's half-written files,
    and an image another process was handed never goes missing: the entry itself is never moved away (it was, and
    of three builds at once two saw their image gone after ``build_images`` returned)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=target.name + ".", dir=target.parent))
    try:
        _make(port, scratch, variants)
        try:
            target.mkdir(exist_ok=True)
        except OSError as error:
            raise DeviceError(f"{target} is not a directory, where the firmware cache keeps its images: move it "
                              "away") from error
        _refuse_what_is_not_a_build_output(target, board, variants)
        for path in scratch.iterdir():  # objects are not kept: only images, binaries and maps
            if path.is_file():
                os.replace(path, target / path.name)  # built from the same sources by the same compiler as any before
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _make(port: Path, out: Path, variants) -> None:
    command = ["make", "--no-print-directory", "-f", str(port / "Makefile"), f"O={out}", *variants]
    try:
        result = subprocess.run(command, capture_output=True, text=True, timeout=BUILD_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired as error:
        raise DeviceError(f"the firmware build took over {BUILD_TIMEOUT_S:g} s and was stopped") from error
    if result.returncode != 0:
        lines = [line for line in (result.stderr + result.stdout).splitlines() if "error" in line.lower()]
        first = lines[0] if lines else (result.stderr.strip().splitlines() or ["(no output)"])[-1]
        raise DeviceError(f"the firmware build failed: {first.strip()}")


def _image(board: str, variant: str, target: Path) -> FirmwareImage:
    elf = target / _elf_name(board, variant)
    map_path = elf.with_suffix(".map")
    binary = elf.with_suffix(".bin")
    flash, ram, stack = map_sizes(map_path.read_text(), board)
    return FirmwareImage(board, variant, str(elf), str(binary) if binary.is_file() else None, str(map_path),
                         flash, ram, stack)
