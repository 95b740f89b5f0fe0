"""A scan setting that is a number must be one that means something: NaN and infinity
are refused where they enter (``ScanSettings``), with one error naming the setting."""

import math

import pytest

from rls_addon.core.errors import SettingsError
from rls_addon.core.scan.settings import LidarSettings, ScanSettings

NAMES = {"min_range_m": "the minimum range (min_range_m, m)",
         "max_range_m": "the maximum range (max_range_m, m)",
         "noise_sigma_m": "the noise sigma (noise_sigma_m, m)",
         "attenuation_per_m": "the attenuation (attenuation_per_m, 1/m)",
         "motion_tolerance_m": "the motion tolerance (motion_tolerance_m, m)",
         "sweep_start_deg": "the sweep start (sweep_start_deg, degrees)"}


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("name", sorted(NAMES))
def test_a_non_finite_number_is_one_settings_error_naming_the_setting(name, value):
    with pytest.raises(SettingsError) as err:
        ScanSettings(**{name: value})
    assert str(err.value) == f"{NAMES[name]} must be a finite number, got {value!r}"
    with pytest.raises(SettingsError):  # as the command line overrides it
        LidarSettings().override(**{name: value})


@pytest.mark.parametrize("name", ["min_range_m", "noise_sigma_m", "attenuation_per_m",
                                  "motion_tolerance_m"])
def test_a_negative_length_or_rate_is_refused(name):
    with pytest.raises(SettingsError, match=r"must be >= 0, got -0\.5$"):
        ScanSettings(**{name: -0.5})


def test_a_maximum_range_must_be_positive():
    with pytest.raises(SettingsError, match=r"^the maximum range \(max_range_m, m\) must be > 0, "
                                            r"got 0\.0$"):
        ScanSettings(max_range_m=0.0)


@pytest.mark.parametrize("value", [math.nan, math.inf])
def test_non_finite_substeps_are_the_sub_steps_error(value):
    with pytest.raises(SettingsError, match=r"^sub-steps must be a whole number >= 0"):
        ScanSettings(substeps=value)


def test_finite_values_and_none_pass():
    s = ScanSettings(min_range_m=0.0, max_range_m=200.0, noise_sigma_m=0.0,
                     attenuation_per_m=0.004, motion_tolerance_m=0.01, sweep_start_deg=-180.0)
    assert s.sweep_start_deg == -180.0
    assert ScanSettings().sweep_start_deg is None
