"""The serial edge: a reader thread that hands every chunk on, and survives unplugging.

pyserial's ``serial_for_url`` opens a device path, a COM port, ``socket://``, ``loop://`` or a
pseudo-terminal alike. The thread reads whatever has arrived, stamps it with the host time and
calls ``on_chunk`` (which writes the raw log *first*, then parses). When the port fails (a
USB-serial adapter pulled out), it reports the gap through ``on_event`` and tries to reopen it
every ``retry_s`` (0.1 s) until the device is back or the reader is stopped: a timer that comes
back is read again within a fraction of a second, not after a growing backoff.

Two things pyserial does by default would lose or tear a test day, and are changed here:

- ``Serial.open()`` on POSIX flushes the input queue (``tcflush(TCIFLUSH)`` at the end of
  ``open``). Whatever the timer sent between the moment the adapter reappeared and the moment
  the port was reopened is in that queue; a start impulse lost there loses the descent. The port
  is opened with :class:`KeepQueuedSerial`, which skips that one flush (an explicit
  ``reset_input_buffer()`` still works).
- Two programs may read one port; each gets some of the bytes, lines are torn between them.
  The port is opened with ``exclusive=True`` (``flock(LOCK_EX | LOCK_NB)`` on the device), and a
  second recorder gets :class:`PortBusy`, an :class:`InputError` naming the process that holds
  the port (found in ``/proc/locks``, else among the open files in ``/proc``).
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable
from typing import Any

import serial

from station.errors import InputError
from station.session.config import SerialConfig

PARITY = {
    "N": serial.PARITY_NONE,
    "E": serial.PARITY_EVEN,
    "O": serial.PARITY_ODD,
    "M": serial.PARITY_MARK,
    "S": serial.PARITY_SPACE,
}

RETRY_S = 0.1


class PortBusy(InputError):
    """The port is locked by another process (another recorder, a terminal program)."""


class KeepQueuedSerial(serial.Serial):
    """pyserial's POSIX port without the input flush in ``open()``: bytes the OS queued while
    nobody had the port open are read, not discarded."""

    _opening = False

    def open(self) -> None:
        self._opening = True
        try:
            super().open()
        finally:
            self._opening = False

    def _reset_input_buffer(self) -> None:
        if self._opening:
            return
        super()._reset_input_buffer()  # type: ignore[misc]  # POSIX Serial has it; stubs do not


def _is_device_path(port: str) -> bool:
    return (
        "://" not in port and os.name == "posix" and hasattr(serial.Serial, "_reset_input_buffer")
    )


def open_port(cfg: SerialConfig, timeout: float = 0.2) -> serial.Serial:
    """Open the timer's port: exclusively, keeping what the OS queued. A port held by another
    process raises :class:`PortBusy`."""
    settings: dict[str, Any] = dict(
        baudrate=cfg.baudrate,
        bytesize=cfg.bytesize,
        parity=PARITY[cfg.parity],
        stopbits=cfg.stopbits,
        rtscts=cfg.rtscts,
        xonxoff=cfg.xonxoff,
        timeout=timeout,
        exclusive=True,
    )
    if not _is_device_path(cfg.port):
        return serial.serial_for_url(cfg.port, **settings)  # loop://, socket:// in tests
    try:
        return KeepQueuedSerial(cfg.port, **settings)
    except serial.SerialException as exc:
        if "exclusively lock" in str(exc):
            raise PortBusy(
                f"the serial port is held by {port_holder(cfg.port)}; "
                "stop that program or choose another port",
                path=cfg.port,
            ) from None
        raise


def ensure_port_free(cfg: SerialConfig) -> None:
    """Raise :class:`PortBusy` now, before a session folder is made, if another process holds
    the port. A port that does not exist (yet) is not an error: the reader waits for it."""
    try:
        port = open_port(cfg)
    except PortBusy:
        raise
    except (serial.SerialException, OSError, ValueError):
        return
    port.close()


def port_holder(path: str) -> str:
    """Who holds ``path``: "process 1234 (station record …)", or "another process"."""
    try:
        st = os.stat(path)
    except OSError:
        return "another process"
    own = os.getpid()
    pids = [p for p in _flock_holders(st) if p != own] or [p for p in _openers(st) if p != own]
    if not pids:
        return "another process"
    return ", ".join(f"process {p}{_cmdline(p)}" for p in pids[:3])


def _flock_holders(st: os.stat_result) -> list[int]:
    """PIDs holding a FLOCK on the inode of ``st`` according to /proc/locks (Linux)."""
    want = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    out = []
    with (
        contextlib.suppress(OSError),
        open("/proc/locks", encoding="ascii", errors="replace") as fh,
    ):
        for line in fh:
            parts = line.split()
            if len(parts) > 5 and parts[1] == "FLOCK" and parts[5] == want:
                with contextlib.suppress(ValueError):
                    if int(parts[4]) > 0:
                        out.append(int(parts[4]))
    return out


def _openers(st: os.stat_result) -> list[int]:
    """PIDs with the device open (those whose /proc/PID/fd we may read)."""
    out = []
    with contextlib.suppress(OSError):
        for name in os.listdir("/proc"):
            if not name.isdigit():
                continue
            fd_dir = f"/proc/{name}/fd"
            with contextlib.suppress(OSError):
                for fd in os.listdir(fd_dir):
                    with contextlib.suppress(OSError):
                        fst = os.stat(os.path.join(fd_dir, fd))
                        if fst.st_ino == st.st_ino and fst.st_dev == st.st_dev:
                            out.append(int(name))
                            break
    return out


def _cmdline(pid: int) -> str:
    with contextlib.suppress(OSError):
        with open(f"/proc/{pid}/cmdline", "rb") as fh:
            args = fh.read().split(b"\0")
        text = " ".join(a.decode("utf-8", "replace") for a in args if a)
        text = " ".join(text.split())  # one line, whatever the command line held
        if len(text) > 80:
            text = text[:77] + "..."
        return f" ({text})" if text else ""
    return ""


class SerialReader(threading.Thread):
    """Reads until stopped; ``on_chunk(t, data)``, ``on_event(t, event, detail)``, and
    ``on_idle(t)`` after every read and every retry while the port is away (for time-outs).

    If the port is held by another process when the reader starts, the reader ends at once with
    ``error`` set to :class:`PortBusy`; if it is taken while the timer was unplugged, that is
    reported once as ``open-failed`` and the reader keeps trying."""

    def __init__(
        self,
        cfg: SerialConfig,
        on_chunk: Callable[[float, bytes], None],
        on_event: Callable[[float, str, str], None],
        on_idle: Callable[[float], None] | None = None,
        retry_s: float = RETRY_S,
    ) -> None:
        super().__init__(name="serial-reader", daemon=True)
        self.cfg = cfg
        self.on_chunk = on_chunk
        self.on_event = on_event
        self.on_idle = on_idle
        self.retry_s = retry_s
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
        port = None
        first = True
        reported = False  # one "open-failed" per gap, not one every retry
        while not self._stop_event.is_set():
            if port is None:
                try:
                    port = open_port(self.cfg)
                except PortBusy as exc:
                    if first:
                        raise
                    if not reported:
                        self.on_event(time.time(), "open-failed", str(exc))
                        reported = True
                    self._idle()
                    self._stop_event.wait(self.retry_s)
                    continue
                except (serial.SerialException, OSError, ValueError) as exc:
                    if first:
                        self.on_event(time.time(), "open-failed", str(exc))
                        first = False
                        reported = True
                    self._idle()
                    self._stop_event.wait(self.retry_s)
                    continue
                self.connected = True
                self.on_event(time.time(), "connected", self.cfg.port)
                first = reported = False
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
                reported = True  # "disconnected" said it; stay quiet while it is away
                continue
            now = time.time()
            if data:
                self.on_chunk(now, data)
            if self.on_idle is not None:
                self.on_idle(now)
        if port is not None:
            port.close()

    def _idle(self) -> None:
        """While the port is away, the host clock still ends a descent whose time-out passed:
        a skier is off the run whether the cable is in or not. Without it an open descent
        stayed open for as long as the timer was unplugged (for ever at the end of a day), and
        ``station record --max-descents N`` never ended."""
        if self.on_idle is not None:
            self.on_idle(time.time())
