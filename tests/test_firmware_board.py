"""The netduinoplus2 port's pure logic, compiled for the host (QEMU models no DAC, DMA, TIM6 or piezo, so
the arithmetic behind them is checked here): register values, sample conversions, the UART ring and the
emulated plate the QEMU image drives."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
PORT = ROOT / "devices" / "firmware" / "ports" / "netduinoplus2"
SHIM = Path(__file__).resolve().parent / "firmware" / "board_shim.c"


@pytest.fixture(scope="module")
def port(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("needs a host C compiler (gcc)")
    library = tmp_path_factory.mktemp("port") / "libport.so"
    subprocess.run(["gcc", "-std=c11", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC", f"-I{PORT}",
                    str(PORT / "port_logic.c"), str(PORT / "emulated_plate.c"), str(SHIM), "-lm", "-o",
                    str(library)], check=True)
    lib = ctypes.CDLL(str(library))
    for name, restype, argtypes in [
        ("ug_usart_brr", ctypes.c_uint32, [ctypes.c_uint32, ctypes.c_uint32]),
        ("ug_usart_baud", ctypes.c_uint32, [ctypes.c_uint32, ctypes.c_uint32]),
        ("ug_timer_arr", ctypes.c_uint32, [ctypes.c_uint32, ctypes.c_uint32]),
        ("ug_timer_rate_hz", ctypes.c_uint32, [ctypes.c_uint32, ctypes.c_uint32]),
        ("ug_dac_code", ctypes.c_uint16, [ctypes.c_int16]),
        ("ug_adc_peak_to_peak", ctypes.c_uint32, [ctypes.POINTER(ctypes.c_uint16), ctypes.c_uint32]),
        ("ug_emulated_plate_gain", ctypes.c_float, [ctypes.c_void_p, ctypes.c_float]),
        ("ug_emulated_plate_step", ctypes.c_float, [ctypes.c_void_p, ctypes.c_float, ctypes.c_float, ctypes.c_float]),
        ("ug_emulated_plate_init", None, [ctypes.c_void_p] + [ctypes.c_float] * 4),
        ("shim_ring_put", ctypes.c_int, [ctypes.c_ubyte]),
        ("shim_ring_get", ctypes.c_int, [ctypes.POINTER(ctypes.c_ubyte)]),
        ("shim_ring_write", ctypes.c_int, [ctypes.c_char_p, ctypes.c_ulong]),
        ("shim_ring_used", ctypes.c_uint, []),
        ("shim_ring_dropped", ctypes.c_uint, []),
        ("shim_ring_set_indices", None, [ctypes.c_uint, ctypes.c_uint]),
        ("shim_ring_size", ctypes.c_uint, []),
    ]:
        function = getattr(lib, name)
        function.restype = restype
        function.argtypes = argtypes
    return lib


def test_usart_divider_for_the_hosts_default_baud_rate(port):
    # RM0090's formula at 16x oversampling: USARTDIV = 84 MHz / (16 × 921 600) = 5.6966 → 5 + 11/16 → 0x5B
    assert port.ug_usart_brr(84_000_000, 921_600) == 0x5B
    assert port.ug_usart_baud(84_000_000, 0x5B) == 923_077
    assert abs(port.ug_usart_baud(84_000_000, 0x5B) / 921_600 - 1) < 0.002  # within a UART's 2 % tolerance
    assert port.ug_usart_brr(84_000_000, 115_200) == 729  # 45.5729 × 16 = 729.17
    assert port.ug_usart_brr(84_000_000, 0) == 0


def test_timer_reload_values(port):
    # TIM6 at 84 MHz pacing the DAC at 250 kHz: 336 counts a sample
    assert port.ug_timer_arr(84_000_000, 250_000) == 335
    assert port.ug_timer_rate_hz(84_000_000, 335) == 250_000
    assert port.ug_timer_arr(48_000_000, 1000) == 47_999  # QEMU's TIM2 counts at 48 MHz
    assert port.ug_timer_arr(84_000_000, 100_000_000) == 1  # never zero: a zero reload stops the timer


@pytest.mark.parametrize(("sample", "code"), [(0, 2048), (16, 2049), (-16, 2047), (8, 2049), (-8, 2047), (7, 2048),
                                              (32767, 4095), (-32768, 0), (32752, 4095), (-32760, 0), (1600, 2148)])
def test_dac_codes_are_the_sample_around_mid_scale(port, sample, code):
    assert port.ug_dac_code(sample) == code


def test_dac_codes_track_a_sine_within_half_a_code(port):
    samples = np.round(30000 * np.sin(np.arange(100) * 2 * np.pi / 10)).astype(np.int16)
    codes = np.array([port.ug_dac_code(int(s)) for s in samples])
    assert np.max(np.abs(codes - (2048 + samples / 16))) <= 0.5
    assert codes.min() >= 0 and codes.max() <= 4095


def test_adc_peak_to_peak(port):
    codes = (ctypes.c_uint16 * 6)(2048, 2300, 1800, 2100, 2047, 1900)
    assert port.ug_adc_peak_to_peak(codes, 6) == 500
    assert port.ug_adc_peak_to_peak(codes, 0) == 0
    assert port.ug_adc_peak_to_peak(codes, 1) == 0


class Plate(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in
                ("resonance_hz", "q", "drift_hz_per_s", "full_scale_um_pp", "elapsed_s", "amplitude_um_pp")]


def test_emulated_plate_resonance_curve_and_settling(port):
    plate = Plate()
    port.ug_emulated_plate_init(ctypes.byref(plate), 25000.0, 200.0, 0.0, 8.0)
    assert port.ug_emulated_plate_gain(ctypes.byref(plate), 25000.0) == pytest.approx(1.0)
    # half-power points at f0 (1 ± 1/2Q): 25 000 ± 62.5 Hz
    assert port.ug_emulated_plate_gain(ctypes.byref(plate), 25062.5) == pytest.approx(1 / math.sqrt(2), rel=1e-5)
    tau_s = 200 / (math.pi * 25000)  # 2.546 ms
    amplitude = port.ug_emulated_plate_step(ctypes.byref(plate), 0.5, 25000.0, tau_s)
    assert amplitude == pytest.approx(4.0 * (1 - math.exp(-1)), rel=1e-5)  # 63 % of the 4 µm step after τ
    for _ in range(100):
        amplitude = port.ug_emulated_plate_step(ctypes.byref(plate), 0.5, 25000.0, 0.001)
    assert amplitude == pytest.approx(4.0, rel=1e-5)
    assert plate.elapsed_s == pytest.approx(tau_s + 0.1, rel=1e-5)


def test_emulated_plate_drifts(port):
    plate = Plate()
    port.ug_emulated_plate_init(ctypes.byref(plate), 25000.0, 200.0, 10.0, 8.0)
    for _ in range(10):
        port.ug_emulated_plate_step(ctypes.byref(plate), 0.0, 25000.0, 0.5)
    assert port.ug_emulated_plate_gain(ctypes.byref(plate), 25050.0) == pytest.approx(1.0, rel=1e-5)  # f0 moved 50 Hz


def test_uart_ring_keeps_order_counts_what_it_drops_and_wraps(port):
    size = port.shim_ring_size()
    port.shim_ring_set_indices(0xFFFF_FFF0, 0xFFFF_FFF0)  # indices about to wrap past 2^32
    data = bytes(range(256)) * (size // 256)
    assert port.shim_ring_write(data, len(data)) == 1
    assert port.shim_ring_used() == size
    assert port.shim_ring_put(7) == 0 and port.shim_ring_dropped() == 1
    assert port.shim_ring_write(b"ab", 2) == 0 and port.shim_ring_dropped() == 3  # all or nothing: a frame is never cut
    byte = ctypes.c_ubyte()
    out = bytearray()
    while port.shim_ring_get(ctypes.byref(byte)):
        out.append(byte.value)
    assert bytes(out) == data
    assert port.shim_ring_used() == 0
