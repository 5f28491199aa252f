"""The board ports' pure logic (ports/common/, shared by netduinoplus2 and mps2-an386), compiled for the host
(QEMU models no DAC, DMA or piezo, so the arithmetic behind them is checked here): register values, the DAC's
words, the sensing piezo's amplitude from ADC samples, the plate the QEMU image drives, the QEMU image's link
tap, the console's numbers and the UART ring. Expectations come from the physics (a resonator's gain, its time
constant), from numpy's reading of the same signals and from the host's own protocol encoder."""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ultraglide.devices import protocol as p

ROOT = Path(__file__).resolve().parent.parent
PORT = ROOT / "devices" / "firmware" / "ports" / "common"
SHIM = Path(__file__).resolve().parent / "firmware" / "board_shim.c"
DAC_RATE = 240_000  # board.h: BOARD_DAC_RATE_HZ, the ADC's rate too
PER_DRIVE = 5  # ADC samples a drive sample


class Sense(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in ("um_pp_per_code", "mid_code", "two_cos", "inv_sin2", "adc_rate_hz")]


class Plate(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in
                ("resonance_hz", "q", "drift_hz_per_s", "full_scale_um_pp", "sample_rate_hz", "um_pp_per_code",
                 "elapsed_s", "y1", "y2", "peak_um_pp")]


class Tap(ctypes.Structure):
    _fields_ = [("body", ctypes.c_uint8 * 1024), ("length", ctypes.c_uint32), ("left", ctypes.c_uint8),
                ("zero_after", ctypes.c_uint8), ("broken", ctypes.c_uint8), ("limit_code", ctypes.c_uint16),
                ("frames", ctypes.c_uint32), ("bad_frames", ctypes.c_uint32), ("setpoints", ctypes.c_uint32),
                ("above", ctypes.c_uint32), ("max_code", ctypes.c_uint32)]


@pytest.fixture(scope="module")
def port(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("needs a host C compiler (gcc)")
    library = tmp_path_factory.mktemp("port") / "libport.so"
    flags = ["-std=c11", "-Wall", "-Wextra", "-Werror", "-Wshadow", "-Wdouble-promotion", "-O2", "-shared", "-fPIC"]
    sources = [PORT / "port_logic.c", PORT / "emulated_plate.c", PORT / "link_tap.c", SHIM]
    subprocess.run(["gcc", *flags, f"-I{PORT}", *map(str, sources), "-lm", "-o", str(library)], check=True)
    lib = ctypes.CDLL(str(library))
    voidp, f32, u32 = ctypes.c_void_p, ctypes.c_float, ctypes.c_uint32
    for name, restype, argtypes in [
        ("ug_usart_brr", u32, [u32, u32]),
        ("ug_usart_baud", u32, [u32, u32]),
        ("ug_timer_arr", u32, [u32, u32]),
        ("ug_timer_rate_hz", u32, [u32, u32]),
        ("ug_clock_samples_since_block", u32, [u32, u32, u32, u32]),
        ("ug_dma_samples_since_block", u32, [u32, u32, u32, u32]),
        ("shim_dac_word", ctypes.c_uint16, [ctypes.c_int16]),
        ("shim_dac_code", ctypes.c_uint16, [ctypes.c_uint16]),
        ("ug_dac_block", None, [voidp, voidp, u32]),
        ("ug_adc_peak_to_peak", u32, [ctypes.POINTER(ctypes.c_uint16), u32]),
        ("ug_sense_init", None, [voidp, f32, f32, f32]),
        ("ug_sense_set_carrier", None, [voidp, f32]),
        ("ug_sense_block", f32, [voidp, voidp, u32, u32, voidp]),
        ("ug_emulated_plate_init", None, [voidp, f32, f32, f32, f32, f32, f32]),
        ("ug_emulated_plate_resonance_hz", f32, [voidp]),
        ("ug_emulated_plate_run", None, [voidp, voidp, voidp, u32]),
        ("ug_tap_init", None, [voidp, ctypes.c_uint16]),
        ("ug_tap_feed", None, [voidp, ctypes.c_char_p, ctypes.c_size_t]),
        ("ug_tap_crc32", u32, [ctypes.c_char_p, ctypes.c_size_t]),
        ("ug_append_fixed", ctypes.c_char_p, [ctypes.c_char_p, ctypes.c_char_p, f32, u32]),
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


def pointer(array: np.ndarray) -> ctypes.c_void_p:
    return ctypes.c_void_p(array.ctypes.data)


def test_usart_divider_for_the_hosts_default_baud_rate(port):
    # RM0090's formula at 16x oversampling: USARTDIV = 84 MHz / (16 × 921 600) = 5.6966 → 5 + 11/16 → 0x5B
    assert port.ug_usart_brr(84_000_000, 921_600) == 0x5B
    assert port.ug_usart_baud(84_000_000, 0x5B) == 923_077
    assert abs(port.ug_usart_baud(84_000_000, 0x5B) / 921_600 - 1) < 0.002  # within a UART's 2 % tolerance
    assert port.ug_usart_brr(84_000_000, 115_200) == 729  # 45.5729 × 16 = 729.17
    assert port.ug_usart_brr(84_000_000, 0) == 0


def test_timer_reload_values(port):
    # TIM2 at 84 MHz triggering the DAC and the ADC at 240 kHz: 350 counts a sample, exactly
    assert port.ug_timer_arr(84_000_000, 240_000) == 349
    assert port.ug_timer_rate_hz(84_000_000, 349) == 240_000
    assert port.ug_timer_arr(84_000_000, 100_000_000) == 1  # never zero: a zero reload stops the timer


# The QEMU images' blocks (1 ms, 48 drive samples at 48 kHz) run by a free-running clock: the netduinoplus2's TIM5
# counts virtual ns (1 000 000 a block, 20 833.3 ns a drive sample), the mps2-an386's TIMER1 its 25 MHz PCLK (25 000
# a block, 520.83 cycles a drive sample). `due` is when the next block falls due; the last ran up to due - a block.
@pytest.mark.parametrize(("now", "due", "per_block", "expected"), [
    (0, 1_000_000, 1_000_000, 0),  # the last block has just ended
    (20_833, 1_000_000, 1_000_000, 0),  # a drive sample less a third of a ns: not yet whole
    (20_834, 1_000_000, 1_000_000, 1),
    (500_000, 1_000_000, 1_000_000, 24),  # half a block
    (999_999, 1_000_000, 1_000_000, 47),  # 47.99995 samples: 47
    (1_000_000, 1_000_000, 1_000_000, 47),  # the next block due and not run yet: still at most 47, never ahead
    (7_300_000, 1_000_000, 1_000_000, 47),  # several due (a late block interrupt)
    (0, 1_000_001, 1_000_000, 0),  # a reading before the last block's end (out of order): 0, not 2^32 - 1
    (2**32 - 250_000 + 260, 2**32 - 250_000 + 1_000_000, 1_000_000, 0),  # wrapping: 260 ns past the end
    (130_000, 2**32 - 250_000 + 1_000_000, 1_000_000, 18),  # 380 000 ns past the end, across the wrap: 18.24
    (25_000 + 521, 50_000, 25_000, 1),  # TIMER1: 521 cycles are one drive sample (520.83)
    (25_000 + 520, 50_000, 25_000, 0),
    (25_000 + 12_500, 50_000, 25_000, 24),
    (49_999, 50_000, 25_000, 47),
])
def test_samples_since_block_from_a_free_running_clock(port, now, due, per_block, expected):
    assert port.ug_clock_samples_since_block(now % 2**32, due % 2**32, per_block, 48) == expected


# The netduinoplus2's ADC DMA: 2 halves of 240 conversions (48 drive samples x 5), NDTR counting down from 480.
@pytest.mark.parametrize(("ndtr", "pending", "expected"), [
    (480, 0, 0),  # at the start of the first half
    (476, 0, 0),  # 4 conversions: not yet a drive sample
    (475, 0, 1),  # 5 conversions: one
    (241, 0, 47),  # 239 conversions: 47.8
    (240, 0, 0),  # the first half done: the second just started (its block given to the core)
    (120, 0, 24),  # 120 into the second half
    (1, 0, 47),
    (0, 0, 0),  # a stream not enabled (NDTR 0): nothing taken
    (470, 1, 47),  # the second half completed and not yet given to the core: a block behind, 47 at most
    (200, 1, 47),
])
def test_samples_since_block_from_the_adc_dma(port, ndtr, pending, expected):
    assert port.ug_dma_samples_since_block(ndtr, 240, 5, pending) == expected


@pytest.mark.parametrize(("sample", "word", "code"), [(0, 0x8000, 2048), (16, 0x8010, 2049), (-16, 0x7FF0, 2047),
                                                      (15, 0x800F, 2048), (-1, 0x7FFF, 2047), (32767, 0xFFFF, 4095),
                                                      (-32768, 0x0000, 0), (-32767, 0x0001, 0), (1600, 0x8640, 2148)])
def test_dac_words_are_offset_binary_and_the_dac_keeps_their_top_12_bits(port, sample, word, code):
    assert port.shim_dac_word(sample) == word
    assert port.shim_dac_code(word) == code


def test_a_block_of_dac_words_tracks_the_carrier_within_one_code(port):
    samples = np.round(30000 * np.sin(np.arange(240) * 2 * np.pi * 25000 / DAC_RATE)).astype(np.int16)
    words = np.zeros(240, dtype=np.uint16)
    port.ug_dac_block(pointer(samples), pointer(words), 240)
    codes = words >> 4
    assert np.all((codes - (2048 + samples / 16) <= 0) & (codes - (2048 + samples / 16) > -1))  # floor, one code
    assert codes.min() >= 0 and codes.max() <= 4095


def test_adc_peak_to_peak(port):
    codes = (ctypes.c_uint16 * 6)(2048, 2300, 1800, 2100, 2047, 1900)
    assert port.ug_adc_peak_to_peak(codes, 6) == 500
    assert port.ug_adc_peak_to_peak(codes, 0) == 0
    assert port.ug_adc_peak_to_peak(codes, 1) == 0


def adc_codes(amplitude_codes, carrier_hz: float, n: int, mid: float = 2048.0, phase: float = 0.3) -> np.ndarray:
    """A sensing piezo's sinusoid as a 12-bit ADC samples it at DAC_RATE (rounded, clipped)."""
    t = np.arange(n) / DAC_RATE
    x = mid + np.asarray(amplitude_codes) * np.sin(2 * np.pi * carrier_hz * t + phase)
    return np.clip(np.round(x), 0, 4095).astype(np.uint16)


def sense_blocks(port, codes: np.ndarray, carrier_hz: float, um_pp_per_code: float, mid: float = 2048.0) -> np.ndarray:
    sense = Sense()
    port.ug_sense_init(ctypes.byref(sense), DAC_RATE, um_pp_per_code, mid)
    port.ug_sense_set_carrier(ctypes.byref(sense), carrier_hz)
    out = np.zeros(len(codes) // PER_DRIVE, dtype=np.float32)
    block = 48 * PER_DRIVE
    for start in range(0, len(codes), block):
        port.ug_sense_block(ctypes.byref(sense), pointer(codes[start:start + block]), 48, PER_DRIVE,
                            pointer(out[start // PER_DRIVE:]))
    return out


@pytest.mark.parametrize("carrier_hz", [20000.0, 25000.0, 28000.0])
@pytest.mark.parametrize(("amplitude_um_pp", "tolerance"), [(6.0, 0.002), (0.9, 0.01), (0.2, 0.05)])
def test_sensing_reads_the_amplitude_of_each_drive_sample(port, carrier_hz, amplitude_um_pp, tolerance):
    um_pp_per_code = 10.0 / 4096  # 10 µm p-p over the ADC's range
    codes = adc_codes(amplitude_um_pp / 2 / um_pp_per_code, carrier_hz, 240 * 20)
    measured = sense_blocks(port, codes, carrier_hz, um_pp_per_code)
    assert np.abs(measured / amplitude_um_pp - 1).max() < tolerance  # every drive sample, quantised to 12 bits


def test_sensing_follows_a_step_within_a_drive_sample_and_the_bias_of_the_conditioning(port):
    um_pp_per_code = 10.0 / 4096
    n = 240 * 400
    envelope = np.where(np.arange(n) < n // 2, 400.0, 800.0)  # codes: 1.95 then 3.9 µm p-p, a step mid-block
    codes = adc_codes(envelope, 25000.0, n, mid=2100.0)  # the conditioning's bias 52 codes above mid-scale
    measured = sense_blocks(port, codes, 25000.0, um_pp_per_code)
    drive = np.arange(n // PER_DRIVE)
    before, after = measured[(drive > 300 * 48) & (drive < n // PER_DRIVE // 2)], measured[drive > n // PER_DRIVE // 2]
    assert before == pytest.approx(800 * um_pp_per_code, rel=0.005)  # once the bias is learnt (64 blocks)
    assert after == pytest.approx(1600 * um_pp_per_code, rel=0.005)  # from the first drive sample after the step


def run_plate(port, plate: Plate, drive: np.ndarray, carrier_hz: float) -> np.ndarray:
    """Drive the emulated plate with a carrier whose envelope is ``drive`` (fraction of full scale, one value a
    DAC sample) and return its ADC codes."""
    samples = np.round(32767 * drive * np.sin(2 * np.pi * carrier_hz * np.arange(len(drive)) / DAC_RATE))
    words = (samples.astype(np.int16).view(np.uint16) ^ 0x8000).astype(np.uint16)
    adc = np.zeros(len(drive), dtype=np.uint16)
    for start in range(0, len(drive), 240):
        port.ug_emulated_plate_run(ctypes.byref(plate), pointer(words[start:]), pointer(adc[start:]),
                                   min(240, len(drive) - start))
    return adc


def amplitude_um_pp(adc: np.ndarray, carrier_hz: float, um_pp_per_code: float) -> float:
    """The peak-to-peak amplitude of the ADC's sinusoid at carrier_hz, by least squares (numpy)."""
    t = np.arange(len(adc)) / DAC_RATE
    basis = np.column_stack([np.sin(2 * np.pi * carrier_hz * t), np.cos(2 * np.pi * carrier_hz * t), np.ones_like(t)])
    (a, b, _), *_ = np.linalg.lstsq(basis, adc.astype(float), rcond=None)
    return 2 * math.hypot(a, b) * um_pp_per_code


def test_the_emulated_plate_is_a_resonator_of_its_f0_q_and_full_scale(port):
    f0, q, full_scale = 25000.0, 200.0, 8.0
    um_pp_per_code = 1.25 * full_scale / 4096
    steady = DAC_RATE // 10  # 100 ms: 39 time constants of 2.5 ms
    for carrier_hz, drive, expected in [(f0, 1.0, full_scale), (f0, 0.5, 4.0),
                                        (f0 * (1 + 1 / (2 * q)), 1.0, full_scale / math.sqrt(2)),  # half power
                                        (f0 * (1 - 1 / (2 * q)), 1.0, full_scale / math.sqrt(2)),
                                        (f0 * (1 + 1 / q), 1.0, full_scale / math.sqrt(5))]:  # 2Q df/f0 = 2
        plate = Plate()
        port.ug_emulated_plate_init(ctypes.byref(plate), f0, q, 0.0, full_scale, DAC_RATE, um_pp_per_code)
        adc = run_plate(port, plate, np.full(steady, drive), carrier_hz)
        assert amplitude_um_pp(adc[-2400:], carrier_hz, um_pp_per_code) == pytest.approx(expected, rel=0.005)
        if carrier_hz == f0:  # at resonance the envelope rises to its steady value; off it, it beats on the way
            assert plate.peak_um_pp == pytest.approx(expected, rel=0.01)
        else:
            assert plate.peak_um_pp > expected * 0.99


def test_the_emulated_plates_envelope_rises_with_its_time_constant(port):
    f0, q, full_scale = 25000.0, 200.0, 8.0
    um_pp_per_code = 1.25 * full_scale / 4096
    tau_s = q / (math.pi * f0)  # 2.546 ms
    plate = Plate()
    port.ug_emulated_plate_init(ctypes.byref(plate), f0, q, 0.0, full_scale, DAC_RATE, um_pp_per_code)
    adc = run_plate(port, plate, np.full(DAC_RATE // 50, 0.5), f0)
    for after_s in (0.5 * tau_s, tau_s, 2 * tau_s):
        end = int(after_s * DAC_RATE)
        window = adc[end - 48:end + 48]  # ten carrier periods around the moment
        expected = 4.0 * (1 - math.exp(-after_s / tau_s))
        assert amplitude_um_pp(window, f0, um_pp_per_code) == pytest.approx(expected, rel=0.02)


def test_the_emulated_plate_drifts(port):
    plate = Plate()
    port.ug_emulated_plate_init(ctypes.byref(plate), 25000.0, 200.0, 10.0, 8.0, DAC_RATE, 0.0025)
    run_plate(port, plate, np.zeros(DAC_RATE * 5), 25000.0)
    assert port.ug_emulated_plate_resonance_hz(ctypes.byref(plate)) == pytest.approx(25050.0, abs=0.01)
    adc = run_plate(port, plate, np.full(DAC_RATE // 10, 1.0), 25050.0)  # driven where it now resonates
    assert amplitude_um_pp(adc[-2400:], 25050.0, 0.0025) == pytest.approx(8.0, rel=0.005)


def test_sensing_reads_the_emulated_plate(port):
    """The QEMU image's sensing path end to end: the resonator's ADC codes measured as the core gets them."""
    um_pp_per_code = 1.25 * 8.0 / 4096
    plate = Plate()
    port.ug_emulated_plate_init(ctypes.byref(plate), 25000.0, 200.0, 0.0, 8.0, DAC_RATE, um_pp_per_code)
    adc = run_plate(port, plate, np.full(DAC_RATE // 10, 0.75), 25000.0)
    measured = sense_blocks(port, adc, 25000.0, um_pp_per_code)
    assert measured[-480:] == pytest.approx(6.0, rel=0.002)


def test_the_link_tap_counts_the_setpoints_of_valid_frames_only(port):
    tap = Tap()
    limit = round(6.0 / 8.0 * 65535)  # 49151
    port.ug_tap_init(ctypes.byref(tap), limit)
    codes = np.array([0, 1000, limit, limit + 1, 65535, 300], dtype=np.uint16)
    payload = np.uint32(5).tobytes() + np.uint32(12000).tobytes() + np.uint16(len(codes)).tobytes() + codes.tobytes()
    good = p.encode_frame(p.SETPOINTS, 7, payload)
    corrupt = bytearray(p.encode_frame(p.SETPOINTS, 8, payload))
    corrupt[5] ^= 0x40  # a flipped bit: the CRC no longer matches
    hello = p.encode_frame(p.HELLO, 9, p.hello_payload())
    stream = b"\x00\x00" + good + bytes(corrupt) + hello + good
    for start in range(0, len(stream), 7):  # in pieces, as the main loop drains its ring
        piece = stream[start:start + 7]
        port.ug_tap_feed(ctypes.byref(tap), piece, len(piece))
    assert (tap.frames, tap.setpoints, tap.above, tap.max_code, tap.bad_frames) == (2, 12, 4, 65535, 1)
    assert port.ug_tap_crc32(b"123456789", 9) == 0xCBF43926  # CRC-32/IEEE's check value


@pytest.mark.parametrize(("value", "decimals", "text"), [
    (25000.0, 3, "25000.000"), (0.5, 4, "0.5000"), (-1.25, 1, "-1.3"), (6.00004, 4, "6.0000"), (0.0, 0, "0"),
    (float("nan"), 2, "nan"), (float("inf"), 2, "inf"), (123.456, 2, "123.46")])
def test_console_numbers(port, value, decimals, text):
    buffer = ctypes.create_string_buffer(32)
    end = ctypes.cast(ctypes.addressof(buffer) + 32, ctypes.c_char_p)
    port.ug_append_fixed(buffer, end, value, decimals)
    assert buffer.value.decode() == text


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
