"""WGS-84 normal gravity against the values NGA TR8350.2 (3rd ed.) publishes."""

import pytest

from gyrocal.models.gravity import local_gravity_g, normal_gravity_mps2


def test_equator_and_poles_are_the_published_wgs84_values():
    # TR8350.2 Table 3.4: gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2
    assert normal_gravity_mps2(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert normal_gravity_mps2(90.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert normal_gravity_mps2(-90.0) == pytest.approx(9.8321849378, abs=1e-9)


@pytest.mark.parametrize(("latitude_deg", "series_mps2"), [
    # the International Gravity Formula 1980 series 9.780327 (1 + 0.0053024 sin^2 phi
    # - 0.0000058 sin^2 2phi), worked by hand; the series is truncated at ~0.2 mGal
    (30.0, 9.780327 * (1 + 0.0053024 * 0.25 - 0.0000058 * 0.75)),
    (45.0, 9.780327 * (1 + 0.0053024 * 0.5 - 0.0000058 * 1.0)),
    (60.0, 9.780327 * (1 + 0.0053024 * 0.75 - 0.0000058 * 0.75)),
])
def test_mid_latitudes_agree_with_the_1980_series(latitude_deg, series_mps2):
    assert normal_gravity_mps2(latitude_deg) == pytest.approx(series_mps2, abs=2.5e-6)


def test_height_correction_is_the_free_air_gradient():
    # the free-air gradient is about 0.3086 mGal/m (3.086e-6 s^-2) at mid latitudes
    drop = normal_gravity_mps2(45.0, 0.0) - normal_gravity_mps2(45.0, 100.0)
    assert drop / 100.0 == pytest.approx(3.086e-6, rel=2e-3)


def test_in_units_of_standard_g():
    assert local_gravity_g(90.0) == pytest.approx(9.8321849378 / 9.80665, abs=1e-9)


def test_latitude_out_of_range_is_refused():
    with pytest.raises(ValueError, match="latitude"):
        normal_gravity_mps2(91.0)
