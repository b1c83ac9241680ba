"""Local gravity at the station: WGS-84 normal gravity with its height correction.

An accelerometer calibrated against gravity needs the magnitude of gravity
where it stands, not 1 g: between the equator and the poles it differs by
0.5 %, far more than a scale-factor error to be found. The formula is the
WGS-84 normal gravity on the ellipsoid (Somigliana's closed form, NGA
TR8350.2 3rd ed., eq. 4-1, with the constants of its Tables 3.1–3.4) and the
second-order height correction above it (same document, eq. 4-3). It is
*normal* gravity: the real field departs from it by the local gravity
anomaly, typically within ±100 mGal (1e-3 m/s²), which the calibration
carries as a type-B uncertainty (:data:`NORMAL_GRAVITY_ANOMALY_MPS2`) unless
the station gives a measured value.
"""

from __future__ import annotations

import math

#: the standard acceleration of gravity: the unit "g" of accelerometer outputs (CGPM 1901)
STANDARD_GRAVITY_MPS2 = 9.80665

_A_M = 6378137.0                       # semi-major axis
_F = 1.0 / 298.257223563               # flattening
_GAMMA_E = 9.7803253359                # normal gravity at the equator, m/s²
_K = 0.00193185265241                  # Somigliana's constant (b·γp)/(a·γe) − 1
_E2 = 0.00669437999013                 # first eccentricity squared
_M = 0.00344978650684                  # ω²a²b/GM

#: ± half-width of the gravity anomaly assumed when only latitude and height are known (m/s²)
NORMAL_GRAVITY_ANOMALY_MPS2 = 1.0e-3


def normal_gravity_mps2(latitude_deg: float, height_m: float = 0.0) -> float:
    """WGS-84 normal gravity at geodetic latitude and ellipsoidal height, m/s²."""
    if not -90.0 <= latitude_deg <= 90.0:
        raise ValueError(f"latitude must lie in [-90, 90] deg, got {latitude_deg!r}")
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    surface = _GAMMA_E * (1.0 + _K * s2) / math.sqrt(1.0 - _E2 * s2)
    h = float(height_m)
    return surface * (1.0 - 2.0 / _A_M * (1.0 + _F + _M - 2.0 * _F * s2) * h + 3.0 / _A_M**2 * h * h)


def local_gravity_g(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity in units of the standard g (what a perfect accelerometer reads, level)."""
    return normal_gravity_mps2(latitude_deg, height_m) / STANDARD_GRAVITY_MPS2
