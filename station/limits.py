"""The plausible range of every number people type about a descent: one table, so the station
config, the UI's metadata form and the command line refuse the same typos (``--mass 880``,
``--pressure-hpa 8350``) instead of each keeping ranges of its own, or none.

Pure data, imported on the fit's start-up path: no imports beyond the standard library."""

from __future__ import annotations

#: key -> (lowest, highest, unit)
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "mass_kg": (20.0, 200.0, "kg"),  # skier with equipment
    "pressure_hpa": (300.0, 1100.0, "hPa"),  # station pressure from sea level to 9 000 m
    "air_temperature_c": (-60.0, 50.0, "°C"),
    "snow_temperature_c": (-60.0, 5.0, "°C"),
    "humidity_pct": (0.0, 100.0, "%"),
    "air_density": (0.3, 2.0, "kg/m³"),
    "wind_ms": (0.0, 60.0, "m/s"),
    "wind_from_deg": (0.0, 360.0, "° from north"),
    "latitude_deg": (-90.0, 90.0, "°"),  # geodetic, + north: local gravity
    "altitude_m": (-500.0, 9000.0, "m"),  # of the run above sea level
}
