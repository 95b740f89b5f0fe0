"""How far from a scene's origin coordinates may lie: Blender keeps mesh vertices and
keyframe values as float32, whose steps grow with the value (``numpy.spacing``): 7.8 mm
between 65,536 and 131,072 m, 1 m at 1.7e7 m, and nothing beyond 3.4e38 (it overflows).
Coordinates that RLS writes into a scene from another tool's files (a SUMO network's
lanes, FCD positions) are therefore refused beyond ``SPAN_M`` of the scene's origin, with
the limit named, instead of being rounded or overflowing silently.
"""

import numpy as np

from ..errors import InputError

SPAN_M = 1e5
STEP_AT_SPAN_M = float(np.spacing(np.float32(SPAN_M)))  # 0.0078125


def limit_text():
    return (f"{SPAN_M:g} m of the scene's origin (Blender stores coordinates as float32, "
            f"which keeps {STEP_AT_SPAN_M * 1000:.1f} mm steps only that near)")


def check_span(values, what, hint=""):
    """``InputError`` naming ``what`` when any of ``values`` (scene coordinates, m) is
    farther than ``SPAN_M`` from 0 (or not finite); ``hint`` ends the message."""
    v = np.asarray(values, dtype=np.float64)
    if not v.size:
        return
    worst = float(np.max(np.abs(v))) if np.isfinite(v).all() else float("inf")
    if worst > SPAN_M:
        raise InputError(f"{what} lies {worst:.6g} m from the scene's origin: RLS takes "
                         f"coordinates within {limit_text()}{hint}")
