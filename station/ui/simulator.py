"""The simulated timer of ``station demo``: a process of its own on a real pseudo-terminal, as
a real timer would be. ``station`` never imports the simulators; it runs
``python -m simulators.timer`` and reads the port from its first line (``PORT <path>``)."""

from __future__ import annotations

import subprocess


class SimulatorError(RuntimeError):
    """The simulated timer could not be started."""


class SimulatedTimer:
    """Start, and stop, the simulator process."""

    def __init__(self, command: list[str]) -> None:
        self.command = command
        self.process: subprocess.Popen | None = None

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
        return first.split(" ", 1)[1].strip()

    def stop(self) -> None:
        if self.process is None:
            return
        self.process.terminate()
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
