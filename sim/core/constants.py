"""Physical constants and unit factors, defined once (SI)."""

from __future__ import annotations

STANDARD_GRAVITY = 9.80665  # standard acceleration of gravity [m/s^2] (ISO 80000-3)
FT = 0.3048  # m per international foot
KT = 1852.0 / 3600.0  # m/s per knot
SLUG_FT2 = 1.3558179483314004  # kg m^2 per slug ft^2
