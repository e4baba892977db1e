"""station: the measurement station for ski-friction test days.

Data flows one way: survey -> track profile; photocell times -> fit of the particle model of
Kaps, Nachbauer & Mössner (1996) -> μ, CdA, v0 with confidence intervals.
"""

__version__ = "0.1.0"
