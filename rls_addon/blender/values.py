"""Property values as the user typed them. Blender keeps a ``FloatProperty`` in 32 bits,
so a 0.7 typed into a panel reads back as 0.699999988079071; ``typed_float`` gives the
shortest decimal that is the same 32-bit float (0.7), so a setting typed into a panel
is the same number as the command line's flag (a disk radius 1.2e-8 m smaller moves
points across disk edges: the study's InfraNUC differed from ``rls study``'s in the
7th digit)."""

import numpy as np


def typed_float(value):
    """The shortest decimal that a 32-bit float ``value`` is (``float(0.7f) -> 0.7``)."""
    return float(np.format_float_positional(np.float32(value), unique=True, trim="-"))
