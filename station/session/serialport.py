"""The serial edge: a reader thread that hands every chunk on, and survives unplugging.

pyserial's ``serial_for_url`` opens a device path, a COM port, ``socket://``, ``loop://`` or a
pseudo-terminal alike. The thread reads whatever has arrived, stamps it with the host time and
calls ``on_chunk`` (which writes the raw log *first*, then parses). When the port fails (a
USB-serial adapter pulled out), it reports the gap through ``on_event`` and reopens with
backoff (0.5 s doubling to 5 s) until the device is back or the reader is stopped.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable

import serial

from station.session.config import SerialConfig

PARITY = {
    "N": serial.PARITY_NONE,
    "E": serial.PARITY_EVEN,
    "O": serial.PARITY_ODD,
    "M": serial.PARITY_MARK,
    "S": serial.PARITY_SPACE,
}


def open_port(cfg: SerialConfig, timeout: float = 0.2) -> serial.Serial:
    return serial.serial_for_url(
        cfg.port,
        baudrate=cfg.baudrate,
        bytesize=cfg.bytesize,
        parity=PARITY[cfg.parity],
        stopbits=cfg.stopbits,
        rtscts=cfg.rtscts,
        xonxoff=cfg.xonxoff,
        timeout=timeout,
    )


class SerialReader(threading.Thread):
    """Reads until stopped; ``on_chunk(t, data)``, ``on_event(t, event, detail)``, and
    ``on_idle(t)`` after every read (for time-outs)."""

    def __init__(
        self,
        cfg: SerialConfig,
        on_chunk: Callable[[float, bytes], None],
        on_event: Callable[[float, str, str], None],
        on_idle: Callable[[float], None] | None = None,
        max_backoff_s: float = 5.0,
    ) -> None:
        super().__init__(name="serial-reader", daemon=True)
        self.cfg = cfg
        self.on_chunk = on_chunk
        self.on_event = on_event
        self.on_idle = on_idle
        self.max_backoff_s = max_backoff_s
        self._stop_event = threading.Event()
        self.connected = False
        self.error: BaseException | None = None

    def stop(self) -> None:
        self._stop_event.set()

    def run(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # a failure in on_chunk (disk full): stop, loudly
            self.error = exc

    def _run(self) -> None:
        backoff = 0.5
        port = None
        first = True
        while not self._stop_event.is_set():
            if port is None:
                try:
                    port = open_port(self.cfg)
                except (serial.SerialException, OSError, ValueError) as exc:
                    if first:
                        self.on_event(time.time(), "open-failed", str(exc))
                        first = False
                    self._stop_event.wait(backoff)
                    backoff = min(backoff * 2, self.max_backoff_s)
                    continue
                self.connected = True
                self.on_event(time.time(), "connected", self.cfg.port)
                backoff, first = 0.5, False
            try:
                data = port.read(max(1, port.in_waiting or 1))
                if data and port.in_waiting:
                    data += port.read(port.in_waiting)
            except (serial.SerialException, OSError, TypeError) as exc:
                self.connected = False
                self.on_event(time.time(), "disconnected", str(exc))
                with contextlib.suppress(serial.SerialException, OSError):
                    port.close()
                port = None
                continue
            now = time.time()
            if data:
                self.on_chunk(now, data)
            if self.on_idle is not None:
                self.on_idle(now)
        if port is not None:
            port.close()
