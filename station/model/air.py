"""Air density from station pressure, temperature and relative humidity.

ρ = (p − e)/(R_d·T) + e/(R_v·T), e = RH·e_s(T), e_s by Arden Buck over water (meteorological
sensors give RH with respect to water even below 0 °C). Good to about 0.1 % against CIPM-2007,
which is far below what wind and posture do to CdA (friction-physics.md §3.5). Use *station*
pressure, not the sea-level QNH of a weather report: that is 12 % off per 1000 m.
"""

from __future__ import annotations

import math

R_DRY = 287.05  # J kg⁻¹ K⁻¹
R_VAPOUR = 461.495  # J kg⁻¹ K⁻¹

#: used when the user gives no air data; printed with every result that relies on it
DEFAULT_PRESSURE_HPA = 1013.25
DEFAULT_TEMPERATURE_C = 0.0
DEFAULT_HUMIDITY_PCT = 80.0


def saturation_vapour_pressure_hpa(temperature_c: float) -> float:
    """Arden Buck (1996) over water, hPa."""
    t = temperature_c
    return 6.1121 * math.exp((18.678 - t / 234.5) * (t / (257.14 + t)))


def air_density(pressure_hpa: float, temperature_c: float, humidity_pct: float = 0.0) -> float:
    """Density of humid air in kg/m³."""
    if pressure_hpa <= 0:
        raise ValueError("pressure must be positive")
    if not -100.0 < temperature_c < 100.0:
        raise ValueError("temperature out of range (-100 .. 100 °C)")
    if not 0.0 <= humidity_pct <= 100.0:
        raise ValueError("relative humidity must lie between 0 and 100 %")
    t_k = temperature_c + 273.15
    p = pressure_hpa * 100.0
    e = humidity_pct / 100.0 * saturation_vapour_pressure_hpa(temperature_c) * 100.0
    return (p - e) / (R_DRY * t_k) + e / (R_VAPOUR * t_k)


def isa_pressure_hpa(altitude_m: float) -> float:
    """International Standard Atmosphere pressure at an altitude, hPa (±3 % with the weather)."""
    return 1013.25 * (1.0 - 2.25577e-5 * altitude_m) ** 5.25588
