"""What outputs are there: audio devices with the rates they accept, serial ports, the simulator."""

from __future__ import annotations

from ultraglide.devices.errors import DeviceError


def list_devices() -> dict:
    """Audio outputs (with accepted rates), serial ports and the simulator, as plain data."""
    from serial.tools import list_ports

    result: dict = {"simulator": {"url": "sim", "description": "the built-in simulated plate"},
                    "serial": [], "audio": [], "audio_error": None}
    for port in list_ports.comports():
        result["serial"].append({"url": f"serial:{port.device}", "description": port.description,
                                 "hwid": port.hwid})
    try:
        from ultraglide.devices.sinks.audio import import_sounddevice, supported_rates

        sd = import_sounddevice()
        for index, device in enumerate(sd.query_devices()):
            if device["max_output_channels"] < 1:
                continue
            result["audio"].append({"url": f"audio:{index}", "name": device["name"],
                                    "hostapi": sd.query_hostapis(device["hostapi"])["name"],
                                    "rates_hz": supported_rates(index)})
    except DeviceError as error:
        result["audio_error"] = str(error)
    return result
