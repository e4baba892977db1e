"""Finding the timer: the serial ports of this machine, and a check of the configured port
before a recording starts.

A wrong port used to give one "retrying" line and then silence; at the trackside the engineer
needs to see at once that ``/dev/ttyUSB0`` is not there, which ports are (the USB-serial
adapter shows up with its maker), and that on Linux the user must be in the ``dialout`` group.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

from station.errors import InputError

DIALOUT_HINT = "add yourself to the dialout group (sudo usermod -aG dialout $USER) and log in again"


@dataclass(frozen=True)
class SerialPortInfo:
    """One serial port as the operating system describes it."""

    device: str  # /dev/ttyUSB0, COM3
    description: str  # "FT232R USB UART", "n/a" for a bare on-board port
    hwid: str  # "USB VID:PID=0403:6001 SER=A50285BI LOCATION=1-1.2", "n/a"
    manufacturer: str = ""

    def line(self) -> str:
        desc = self.description if self.description not in ("", "n/a") else "serial port"
        extra = [x for x in (self.manufacturer, self.hwid) if x and x != "n/a"]
        return f"{self.device}  {desc}" + (f"  ({'; '.join(extra)})" if extra else "")

    @property
    def is_usb(self) -> bool:
        return self.hwid.startswith("USB")


def list_serial_ports() -> list[SerialPortInfo]:
    """The serial ports pyserial finds (``serial.tools.list_ports``), USB adapters first."""
    from serial.tools import list_ports

    found = [
        SerialPortInfo(
            device=p.device,
            description=str(p.description or ""),
            hwid=str(p.hwid or ""),
            manufacturer=str(getattr(p, "manufacturer", "") or ""),
        )
        for p in list_ports.comports(include_links=True)
    ]
    return sorted(found, key=lambda p: (not p.is_usb, p.device))


def ports_summary(ports: list[SerialPortInfo] | None = None) -> str:
    """The ports in one phrase, for an error line."""
    ports = list_serial_ports() if ports is None else ports
    if not ports:
        return "no serial port found: is the USB-serial adapter plugged in?"
    return "ports found: " + ", ".join(
        p.device + (f" ({p.description})" if p.description not in ("", "n/a") else "")
        for p in ports
    )


def check_port(
    port: str, config_path: str | None = None, ports: list[SerialPortInfo] | None = None
) -> None:
    """Refuse a port that cannot be the timer, in one line that lists the ports there are.

    URLs (``socket://``, ``loop://``, ``rfc2217://``) are pyserial's to open and pass as they
    are; so does a device that exists (a pseudo-terminal of ``station-sim`` included)."""
    if "://" in port:
        return
    if sys.platform == "win32":
        found = list_serial_ports() if ports is None else ports
        exists = port.upper() in [p.device.upper() for p in found]
    else:
        exists = os.path.exists(port)
    if not exists:
        raise InputError(
            f"serial port {port} does not exist; {ports_summary(ports)} (station ports lists them)",
            path=config_path,
            field="serial.port",
        )
    if not os.access(port, os.R_OK | os.W_OK):
        raise InputError(
            f"no permission to open {port}: {DIALOUT_HINT}", path=config_path, field="serial.port"
        )
