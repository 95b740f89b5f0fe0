"""Detection by the LiDAR equation, calibrated from a datasheet's "range at reflectivity"
figures (see docs/realism.md for the equations, constants and sources).

A return's received power, relative to the device's own constants, is

    P = rho * |cos(theta)| * T^2 / R^2

(rho: the surface's reflectivity, theta: incidence, R: range, T: one-way transmission
of the air, 1 in clear weather). A datasheet figure "R_i m at rho_i" says that a flat
Lambertian target of reflectivity rho_i facing the sensor at R_i is detected with the
probability the figure stands for (``probability``, 0.9 unless the preset says
otherwise): the power rho_i / R_i^2 is detected with that probability. Several figures
give one threshold, the geometric mean of their powers; how far each figure lies from
it is ``DetectionModel.spread``. Around the threshold the detection probability is a
logistic in ln P of width ``width``:

    p(P) = 1 / (1 + exp(-(ln P - ln P50) / width)),
    ln P50 = ln P_fig - width * logit(probability)

so p(P_fig) = probability. The width comes from a threshold detector in Gaussian noise
set for a false-alarm ratio of 1e-4 (the 0.01 % of the Livox HAP and the 1/10,000 of the
Ouster OS1 datasheets): threshold 3.72 sigma, detection 10 % at 2.44 sigma and 90 % at
5.00 sigma of signal, a factor 2.05 in received power between them; the logistic that
rises from 10 % to 90 % over that factor has width ln(2.05) / (2 logit(0.9)) = 0.164.
"""

import math
from dataclasses import dataclass, field

import numpy as np

# The intensity a device reports: its calibrated reflectivity (rho |cos| T^2), a raw
# return strength (``DetectionModel.strength``) or CARLA's reflectivity x |cos| x
# exp(-a d) (what RLS reported before this model).
INTENSITY_MODES = ("reflectivity", "strength", "carla")
DEFAULT_PROBABILITY = 0.9
DEFAULT_WIDTH = 0.164
# "strength": ln(P / P50) over this many nepers of dynamic range, clipped to 0..1:
# 0 at the 50 % detection threshold, 1 at 40 dB (10^4) above it and beyond.
STRENGTH_DYNAMIC_RANGE = 1e4


def logit(p):
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class DetectionModel:
    """A preset's ``[detection]`` table: figures ((reflectivity 0..1, range m), ...), the
    detection probability they stand for, the reported intensity and the logistic's
    width (in ln received power)."""

    figures: tuple
    probability: float = DEFAULT_PROBABILITY
    intensity: str = "reflectivity"
    width: float = DEFAULT_WIDTH
    log_p50: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        logs = [math.log(rho) - 2.0 * math.log(r) for rho, r in self.figures]
        object.__setattr__(self, "log_p50",
                           sum(logs) / len(logs) - self.width * logit(self.probability))

    @property
    def threshold(self):
        """The received power detected with ``probability``: the geometric mean of the
        figures' rho / R^2."""
        return math.exp(self.log_p50 + self.width * logit(self.probability))

    @property
    def threshold_50(self):
        """The received power detected half of the time."""
        return math.exp(self.log_p50)

    def excess(self, power):
        """ln(P / P50) of received powers (array; -inf for P = 0): what
        ``probability_of`` and ``strength`` are made of, to work out once when a frame
        wants both."""
        p = np.asarray(power, np.float64)
        with np.errstate(divide="ignore"):
            return np.log(p) - self.log_p50

    def probability_of(self, power, excess=None):
        """Detection probability of received powers (array; 0 for P <= 0); ``excess``:
        their ``excess``, when already worked out."""
        x = (self.excess(power) if excess is None else excess) / self.width
        return 0.5 + 0.5 * np.tanh(0.5 * x)

    def strength(self, power, excess=None):
        """The raw return strength reported with ``intensity = "strength"``: ln(P / P50)
        over ln(``STRENGTH_DYNAMIC_RANGE``), clipped to 0..1; ``excess`` as in
        ``probability_of``."""
        s = (self.excess(power) if excess is None else excess) / math.log(STRENGTH_DYNAMIC_RANGE)
        return np.clip(s, 0.0, 1.0)

    def range_at(self, reflectivity, probability=None, transmission2=1.0):
        """The range (m) at which a Lambertian target of ``reflectivity`` facing the
        sensor is detected with ``probability`` (default: the figures')."""
        p = self.probability if probability is None else probability
        log_power = self.log_p50 + self.width * logit(p)
        return math.sqrt(reflectivity * transmission2 / math.exp(log_power))

    def spread(self):
        """[(reflectivity, range, range the model gives for it)] per figure: how far the
        one threshold places each figure (the model's range / the figure's = sqrt of
        the power ratio)."""
        return [(rho, r, self.range_at(rho)) for rho, r in self.figures]

    def to_dict(self):
        """The model as a sidecar or ``presets show`` records it."""
        return {"model": "lidar_equation",
                "range_at_reflectivity": [list(f) for f in self.figures],
                "probability_at_range": self.probability, "intensity": self.intensity,
                "logistic_width": self.width, "threshold_power": self.threshold,
                "threshold_power_50": self.threshold_50,
                "model_range_at_figures": [round(m, 3) for _, _, m in self.spread()]}


def detection_of(preset, settings):
    """The ``DetectionModel`` a scan uses: the preset's when it has datasheet figures and
    ``settings.detection`` is "auto"; None (CARLA's model) otherwise."""
    model = getattr(preset, "detection", None)
    if model is None or settings.detection != "auto":
        return None
    return model


def detection_info(preset, settings):
    """The sidecar's record of the detection model of a scan."""
    model = getattr(preset, "detection", None)
    if model is None:
        return {"model": "carla", "reason": "no datasheet range figure in the preset"}
    if settings.detection != "auto":
        return {"model": "carla", "reason": f"detection = '{settings.detection}'"}
    return model.to_dict()
