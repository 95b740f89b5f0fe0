"""A device preset's values after a LiDAR's scan settings, resolved once per (preset,
settings) into one object that the session, the frame and the study read: the range
limits, the range noise, the attenuation, the motion tolerance, the detection model,
the weather and the beam. Each override of ``ScanSettings`` is applied here and
nowhere else."""

import threading
from dataclasses import dataclass

from ..physics.detection import detection_of
from ..physics.footprint import beam_of
from ..physics.weather import parse_weather

DEFAULT_MOTION_TOLERANCE_M = 0.01  # when neither the settings nor the preset give one


@dataclass(frozen=True)
class DeviceValues:
    min_range_m: float        # blind zone (m)
    max_range_m: float        # maximum range (m)
    noise_sigma_m: float      # the range noise's sigma (m) the scan draws with; 0 when off
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
        return cls(
            min_range_m=rng.min_m if s.min_range_m is None else s.min_range_m,
            max_range_m=rng.max_m if s.max_range_m is None else s.max_range_m,
            noise_sigma_m=sigma if s.noise else 0.0,
            attenuation_per_m=(preset.attenuation_per_m if s.attenuation_per_m is None
                               else s.attenuation_per_m),
            # the preset's own noise, not an override: a tolerance of the device
            motion_tolerance_m=(s.motion_tolerance_m or rng.noise_sigma_m
                                or DEFAULT_MOTION_TOLERANCE_M),
            detection=detection_of(preset, s),
            weather=parse_weather(s.weather),
            beam=beam_of(preset, s))


_CACHE = {}
_LOCK = threading.Lock()
_CACHE_SIZE = 64


def device_values(preset, settings):
    """``DeviceValues.resolve(preset, settings)``, worked out once per (preset, settings)
    in this process (a frame asks for it every frame)."""
    key = (id(preset), settings)
    with _LOCK:
        got = _CACHE.get(key)
        if got is not None and got[0] is preset:
            return got[1]
    values = DeviceValues.resolve(preset, settings)
    with _LOCK:
        if len(_CACHE) >= _CACHE_SIZE:
            _CACHE.clear()
        _CACHE[key] = (preset, values)
    return values
