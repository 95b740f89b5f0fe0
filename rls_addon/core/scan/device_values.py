"""A device preset's values after a LiDAR's scan settings, in one object: the range
limits, the range noise, the dropout, the attenuation, the motion tolerance, the
detection model, the weather and the beam. Each override of ``ScanSettings`` is
applied here and nowhere else.

Resolved once by whoever starts a scan and passed down, so what a frame draws with is
what the sidecar records: ``ScanRun`` once per sensor of a run, ``ScanSession.scan``
when it is called without them (a single scan, live coverage), the study's scanner
once per study. ``scan_frame`` takes them in place of the preset (a preset handed to
it is resolved there, for scripts and tests)."""

from dataclasses import dataclass

from ..errors import SettingsError
from ..physics.detection import detection_of
from ..physics.footprint import beam_of
from ..physics.weather import parse_weather

DEFAULT_MOTION_TOLERANCE_M = 0.01  # when neither the settings nor the preset give one


@dataclass(frozen=True)
class DeviceValues:
    min_range_m: float        # blind zone (m)
    max_range_m: float        # maximum range (m)
    noise_sigma_m: float      # the range noise's sigma (m) the scan draws with; 0 when off
    dropout: object           # device.presets.DropoutModel: the preset's (rates, limits)
    attenuation_per_m: float  # CARLA's intensity attenuation (1/m)
    motion_tolerance_m: float  # how far anything may move within one sub-step (m)
    detection: object         # physics.detection.DetectionModel, or None: CARLA's model
    weather: object           # physics.weather.Weather, or None: clear air
    beam: object              # physics.footprint.Beam, or None: thin rays, one return

    @property
    def range_m(self):
        return self.min_range_m, self.max_range_m

    @classmethod
    def resolve(cls, preset, settings):
        """The values of ``preset`` under ``settings`` (a ``ScanSettings``)."""
        s, rng = settings, preset.range
        sigma = rng.noise_sigma_m if s.noise_sigma_m is None else s.noise_sigma_m
        lo = rng.min_m if s.min_range_m is None else s.min_range_m
        hi = rng.max_m if s.max_range_m is None else s.max_range_m
        if lo >= hi:  # every return would be dropped: an empty cloud, exit 0
            lo_from = "the preset's" if s.min_range_m is None else "the override"
            hi_from = "the preset's" if s.max_range_m is None else "the override"
            raise SettingsError(
                f"the minimum range ({lo:g} m, {lo_from}) must be below the maximum range "
                f"({hi:g} m, {hi_from}) of '{preset.id}': no return would be kept; "
                "change the LiDAR's Min Range or Max Range")
        return cls(
            min_range_m=lo,
            max_range_m=hi,
            noise_sigma_m=sigma if s.noise else 0.0,
            dropout=preset.dropout,
            attenuation_per_m=(preset.attenuation_per_m if s.attenuation_per_m is None
                               else s.attenuation_per_m),
            # the preset's own noise, not an override: a tolerance of the device
            motion_tolerance_m=(s.motion_tolerance_m or rng.noise_sigma_m
                                or DEFAULT_MOTION_TOLERANCE_M),
            detection=detection_of(preset, s),
            weather=parse_weather(s.weather),
            beam=beam_of(preset, s))


def device_values(preset, settings):
    """The ``DeviceValues`` of ``preset`` under ``settings`` (a ``ScanSettings``)."""
    return DeviceValues.resolve(preset, settings)
