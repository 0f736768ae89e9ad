"""A 3-D boundary-element reference for the MDR: the normal contact of a rigid sphere or ellipsoid
on a rough elastic half-space (free boundary, FFT-accelerated Boussinesq influence, Polonsky &
Keer's constrained conjugate gradients), batched over surfaces on NumPy or CuPy, quasi-static
rolling, and the rough surfaces to roll on (docs/bem.md)."""

from .hertz import elliptical_ratio, hertz_elliptical, hertz_max_pressure, hertz_pressure
from .rolling import Rolling, roll
from .solver import Contact, solve
from .surfaces import extruded, generator, self_affine

__all__ = ["Contact", "Rolling", "elliptical_ratio", "extruded", "generator", "hertz_elliptical",
           "hertz_max_pressure", "hertz_pressure", "roll", "self_affine", "solve"]
