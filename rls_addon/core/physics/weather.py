"""Weather: fog, rain and snow as an extinction coefficient of the air, and the false
returns their particles send back near the sensor (docs/realism.md has the sources).

A weather is given as a spec string, ``kind:key=value[,key=value]``:

    fog:visibility=50        visibility in metres
    rain:rate=10             rain rate in mm/h
    snow:rate=2              snowfall rate in mm/h water equivalent (type=dry|wet, dry
                             by default)

Extinction coefficient alpha (1/m) of the air, and the two-way transmission of a return
from range R, T^2 = exp(-2 alpha R):

* fog: Koschmieder, alpha = -ln(0.02) / V = 3.912 / V (2 % contrast threshold);
* rain: the empirical specific attenuation of optical links, 1.076 R^0.67 dB/km (rain
  rate R in mm/h; Carbonneau and Wisely 1998, as used throughout the free-space-optics
  literature, e.g. Kaushal and Kaddoum 2017);
* snow: a S^b dB/km with, for 905 nm, dry snow a = 5.42e-5 lambda + 5.4958776, b = 1.38
  and wet snow a = 1.023e-4 lambda + 3.7855466, b = 0.72 (lambda in nm, S in mm/h;
  the same free-space-optics literature).

False returns (backscatter from the particles near the sensor): each ray has one with
probability 1 - exp(-alpha L), L = ``BACKSCATTER_DEPTH_M`` (the depth near the sensor
whose backscatter can trigger the receiver; a stated choice, not a fit), at a range
drawn from the shape of the medium's return in the LiDAR equation, exp(-2 alpha R) / R^2
(the soft-target term of Hahner et al. 2021), between the blind zone (at least
``OVERLAP_M``, where the beam and the receiver's view overlap) and the maximum range. It
replaces the ray's return only when nearer than the first surface the ray meets.
"""

import ctypes
import functools
import math
from dataclasses import dataclass

import numpy as np

from ..native import kernels
from ..errors import SettingsError
from ..native.kernels import Kernel

KOSCHMIEDER = -math.log(0.02)          # 3.912
RAIN_DB_PER_KM = (1.076, 0.67)         # a R^b, R in mm/h
WAVELENGTH_NM = 905.0
SNOW_DB_PER_KM = {"dry": (5.42e-5 * WAVELENGTH_NM + 5.4958776, 1.38),
                  "wet": (1.023e-4 * WAVELENGTH_NM + 3.7855466, 0.72)}
DB_PER_KM = math.log(10.0) / 10.0 / 1000.0   # dB/km -> 1/m
BACKSCATTER_DEPTH_M = 10.0
OVERLAP_M = 1.0
# The medium's equivalent reflectivity within one pulse: pi beta c tau / 2, with
# beta = 0.046 / MOR and MOR = ln(20) / alpha (Hahner et al. 2021, after Rasshofer et
# al. 2011) and their half-power pulse width tau = 20 ns.
BACKSCATTER_PER_EXTINCTION = 0.046 / math.log(20.0)   # beta / alpha, 1/sr
PULSE_S = 20e-9
LIGHT_M_S = 299_792_458.0

KINDS = {"fog": {"visibility"}, "rain": {"rate"}, "snow": {"rate", "type"}}
LIMITS = {"visibility": (1.0, 100_000.0, "m"), "rate": (0.01, 500.0, "mm/h")}
HELP = ("expected 'fog:visibility=METRES', 'rain:rate=MM_PER_H' or "
        "'snow:rate=MM_PER_H[,type=dry|wet]'")


@dataclass(frozen=True)
class Weather:
    kind: str                      # fog | rain | snow
    visibility_m: float = None     # fog
    rate_mm_h: float = None        # rain, snow (water equivalent)
    snow_type: str = "dry"         # snow

    @property
    def alpha(self):
        """Extinction coefficient of the air, 1/m."""
        if self.kind == "fog":
            return KOSCHMIEDER / self.visibility_m
        a, b = RAIN_DB_PER_KM if self.kind == "rain" else SNOW_DB_PER_KM[self.snow_type]
        return a * self.rate_mm_h ** b * DB_PER_KM

    @property
    def spec(self):
        if self.kind == "fog":
            return f"fog:visibility={self.visibility_m:g}"
        if self.kind == "rain":
            return f"rain:rate={self.rate_mm_h:g}"
        return f"snow:rate={self.rate_mm_h:g},type={self.snow_type}"

    def to_dict(self):
        """The sidecar's record of the weather."""
        out = {"spec": self.spec, "kind": self.kind, "extinction_per_m": self.alpha,
               "false_return_probability": false_return_probability(self.alpha),
               "false_return_reflectivity": medium_reflectivity(self.alpha)}
        if self.kind == "fog":
            out["visibility_m"] = self.visibility_m
        else:
            out["rate_mm_h"] = self.rate_mm_h
        if self.kind == "snow":
            out["snow_type"] = self.snow_type
        return out


def parse_weather(spec):
    """A ``Weather`` from a spec string (None, '', 'clear' or 'none': clear weather,
    None); ``SettingsError`` naming what is wrong otherwise."""
    if spec is None:
        return None
    if isinstance(spec, Weather):
        return spec
    if not isinstance(spec, str):
        raise SettingsError(f"weather must be a text like 'fog:visibility=50', got {spec!r}")
    return _parse(spec)


@functools.lru_cache(maxsize=64)
def _parse(spec):
    """``parse_weather`` of a string, kept: every frame of a scan parses the same one
    (a ``Weather`` is frozen; errors are raised anew each time)."""
    text = spec.strip().lower()
    if text in ("", "clear", "none"):
        return None
    kind, sep, rest = text.partition(":")
    kind = kind.strip()
    if kind not in KINDS:
        raise SettingsError(f"weather '{spec}': unknown kind '{kind}'; {HELP}")
    values = {}
    for item in (rest.split(",") if sep else []):
        key, eq, value = (s.strip() for s in item.partition("="))
        if not key and not eq:
            continue
        if not eq or not value:
            raise SettingsError(f"weather '{spec}': '{item.strip()}' is not key=value; {HELP}")
        if key not in KINDS[kind]:
            raise SettingsError(f"weather '{spec}': {kind} has no '{key}' (it takes "
                                f"{', '.join(sorted(KINDS[kind]))}); {HELP}")
        if key in values:
            raise SettingsError(f"weather '{spec}': '{key}' given twice")
        if key == "type":
            if value not in SNOW_DB_PER_KM:
                raise SettingsError(f"weather '{spec}': snow type must be dry or wet, "
                                    f"got '{value}'")
            values[key] = value
            continue
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        lo, hi, unit = LIMITS[key]
        if not (math.isfinite(number) and lo <= number <= hi):
            raise SettingsError(f"weather '{spec}': {key} must be a number from {lo:g} to "
                                f"{hi:g} ({unit}), got '{value}'")
        values[key] = number
    need = "visibility" if kind == "fog" else "rate"
    if need not in values:
        raise SettingsError(f"weather '{spec}': {kind} needs {need}; {HELP}")
    if kind == "fog":
        return Weather("fog", visibility_m=values["visibility"])
    return Weather(kind, rate_mm_h=values["rate"], snow_type=values.get("type", "dry"))


def weather_spec(spec):
    """The canonical spec of a weather (None: clear), validated."""
    w = parse_weather(spec)
    return None if w is None else w.spec


def transmission2(alpha, distance):
    """Two-way transmission exp(-2 alpha d) of the air."""
    return np.exp(-2.0 * float(alpha) * np.asarray(distance, np.float64))


def false_return_probability(alpha):
    """The share of rays that bring back a return from the medium near the sensor."""
    return -math.expm1(-float(alpha) * BACKSCATTER_DEPTH_M)


def medium_reflectivity(alpha):
    """The reflectivity a Lambertian target facing the sensor would need to return what
    the medium returns within one pulse: pi beta c tau / 2 (at most 1)."""
    beta = BACKSCATTER_PER_EXTINCTION * float(alpha)
    return min(1.0, math.pi * beta * LIGHT_M_S * PULSE_S / 2.0)


def false_return_table(alpha, r_near, r_far, grid=4097):
    """(cdf, x): the CDF of the distribution of ``false_return_ranges`` in x = 1 / R,
    tabulated on ``grid`` points of x from 1 / r_far to 1 / r_near. In x the density is
    exp(-2 alpha / x) (uniform when alpha = 0). Read-only, kept for the last few
    weathers: every frame of a scan asks for the same table (0.1 ms to make, as much
    as a small frame's false returns themselves)."""
    return _table(float(alpha), float(r_near), float(r_far), int(grid))


@functools.lru_cache(maxsize=16)
def _table(alpha, r_near, r_far, grid):
    x0, x1 = 1.0 / r_far, 1.0 / r_near
    x = np.linspace(x0, x1, grid)
    f = np.exp(-2.0 * alpha / x)
    cdf = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) * 0.5 * np.diff(x))])
    cdf /= cdf[-1]
    cdf.flags.writeable = x.flags.writeable = False
    return cdf, x


def false_return_ranges(u, alpha, r_near, r_far, grid=4097):
    """Ranges of false returns for uniforms ``u`` (N,): the inverse of the distribution
    with density proportional to exp(-2 alpha R) / R^2 on [r_near, r_far], by
    interpolation in its tabulated CDF (``false_return_table``)."""
    cdf, x = false_return_table(alpha, r_near, r_far, grid)
    # u = 0 is the far end (x0): ranges fall from r_far to r_near as u grows
    return 1.0 / np.interp(np.asarray(u, np.float64), cdf, x)


def false_returns(alpha, u_medium, u_range, hit, dist, r_near, r_far):
    """(rows, ranges) of the rays whose return is a false one from the air: drawn with
    probability ``false_return_probability`` (uniforms ``u_medium``), at a range from
    ``false_return_ranges`` (uniforms ``u_range``), and only where that is nearer than
    the first surface the ray meets (``hit``, at ``dist``). In C (native/c/weather.c)
    where it is built, else ``false_returns_numpy``: the same bytes."""
    fn = FALSE_RETURNS.get() if compiled else None
    if fn is None:
        return false_returns_numpy(alpha, u_medium, u_range, hit, dist, r_near, r_far)
    cdf, x = false_return_table(alpha, r_near, r_far)
    keep = [np.ascontiguousarray(a, t) for a, t in
            ((u_medium, np.float64), (u_range, np.float64), (hit, np.uint8),
             (dist, np.float64), (cdf, np.float64), (x, np.float64))]
    n = len(keep[0])
    rows, ranges = np.empty(n, np.int64), np.empty(n)  # pages touched only as written
    args = _AirArgs(n, keep[0].ctypes.data, keep[1].ctypes.data,
                    false_return_probability(alpha), keep[2].ctypes.data,
                    keep[3].ctypes.data, keep[4].ctypes.data, keep[5].ctypes.data, len(x),
                    rows.ctypes.data, ranges.ctypes.data)
    got = fn(ctypes.byref(args), kernels.threads())
    if got < 0:
        return false_returns_numpy(alpha, u_medium, u_range, hit, dist, r_near, r_far)
    return rows[:got], ranges[:got]


def false_returns_numpy(alpha, u_medium, u_range, hit, dist, r_near, r_far):
    """The reference of ``false_returns``; the range only of the rays that drew a
    false return (each ray's on its own)."""
    drawn = np.nonzero(u_medium < false_return_probability(alpha))[0]
    ranges = false_return_ranges(u_range[drawn], alpha, r_near, r_far)
    near = ranges < np.where(hit[drawn], dist[drawn], np.inf)
    return drawn[near], ranges[near]


class _AirArgs(ctypes.Structure):
    """``air_t`` of native/c/weather.c."""

    _fields_ = [("n", ctypes.c_int64), ("u_medium", ctypes.c_void_p),
                ("u_range", ctypes.c_void_p), ("p", ctypes.c_double),
                ("hit", ctypes.c_void_p), ("dist", ctypes.c_void_p),
                ("cdf", ctypes.c_void_p), ("x", ctypes.c_void_p), ("len", ctypes.c_int64),
                ("rows", ctypes.c_void_p), ("ranges", ctypes.c_void_p)]


NATIVE_WEATHER_ABI = 2
FALSE_RETURNS = Kernel("rls_false_returns", "rls_weather_abi", NATIVE_WEATHER_ABI,
                       [ctypes.POINTER(_AirArgs), ctypes.c_int], ctypes.c_int64)
# Off: every frame draws its false returns in numpy (the reference the C code is
# tested against).
compiled = True


def false_return_pdf(r, alpha, r_near, r_far):
    """The density of ``false_return_ranges`` at ranges ``r`` (for tests and charts)."""
    r = np.asarray(r, np.float64)
    grid = np.linspace(r_near, r_far, 200_001)
    g = np.exp(-2.0 * alpha * grid) / grid ** 2
    norm = np.sum((g[1:] + g[:-1]) * 0.5 * np.diff(grid))
    inside = (r >= r_near) & (r <= r_far)
    return np.where(inside, np.exp(-2.0 * alpha * r) / r ** 2 / norm, 0.0)
