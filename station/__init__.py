"""station: the measurement station for ski-friction test days.

Data flows one way, and the subpackages are named for the stage they hold:

- :mod:`station.survey`  surveyor's readings -> reduced points -> track profile h(x)
- :mod:`station.timing`  timer bytes -> lines -> impulses -> timed descents (pure)
- :mod:`station.model`   the particle model of Kaps, Nachbauer & Mössner (1996): physics, fits,
  the traverse model and the comparison of a day's items (pure)
- :mod:`station.session` a test day: config, raw log, processor, fits of finished descents,
  annotations, results CSV, serial port, acquisition and replay
- :mod:`station.report`  text for people: tables and one-line summaries used by CLI and UI
- :mod:`station.cli`     the ``station`` command, one module per group of subcommands
- :mod:`station.ui`      the trackside terminal UI (the only part that imports textual)
"""

__version__ = "0.1.0"
