"""The simulated timer of ``station demo``: a process of its own on a real pseudo-terminal, as
a real timer would be. ``station`` never imports the simulators; it runs
``python -m station.simulators.timer`` and reads the port from its first line (``PORT <path>``)."""

from __future__ import annotations

import contextlib
import os
import subprocess


class SimulatorError(RuntimeError):
    """The simulated timer could not be started."""


class SimulatedTimer:
    """Start, and stop, the simulator process."""

    def __init__(self, command: list[str]) -> None:
        self.command = command
        self.process: subprocess.Popen | None = None
        self.port = ""

    def start(self) -> str:
        """Start the process; returns the port it opened."""
        try:
            self.process = subprocess.Popen(
                self.command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
            )
        except OSError as exc:
            raise SimulatorError(f"cannot start the simulated timer: {exc}") from None
        first = self.process.stdout.readline() if self.process.stdout else ""
        if not first.startswith("PORT "):
            raise SimulatorError("the simulated timer did not start")
        self.port = first.split(" ", 1)[1].strip()
        return self.port

    def terminate(self) -> None:
        """Ask the simulator to end, without waiting (quitting the UI does both at once)."""
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()

    def stop(self, timeout: float = 5.0) -> None:
        """End the simulator: asked first, killed when it has not ended within ``timeout``
        (it sleeps up to a second between lines; the demo's timer has nothing to save)."""
        if self.process is None:
            return
        self.terminate()
        try:
            self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        if self.port and os.path.islink(self.port):  # killed: its link to the pty is left
            with contextlib.suppress(OSError):
                os.unlink(self.port)
