"""mdroll: the Method of Dimensionality Reduction for a wheel rolling on a rough rail.

Ensembles of random rough lines (physics.md section 3), the contact force by four algorithms
(:data:`ALGORITHMS`: the exact direct sum, an exact bounding tree, an exact O(n) sweep and the
edge-incremental approximation; section 4) as Warp kernels on CPU and CUDA, the wheel's dynamics
(section 5) and ensemble-averaged spectra (section 6). All units SI.
"""

from .devices import available_devices
from .forces.force import contact_force
from .forces.registry import ALGORITHMS
from .forces.steps import BOUNDARIES, step_range
from .ensemble.lines import rough_lines
from .ensemble.pipeline import EnsembleResult, run_ensemble
from ._version import __version__
from .ensemble.spec import EnsembleSpec, run_specs
from .errors import DeviceError, MdrollError, ParameterError
from .params import Params


__all__ = [
    "ALGORITHMS",
    "BOUNDARIES",
    "DeviceError",
    "EnsembleResult",
    "EnsembleSpec",
    "MdrollError",
    "ParameterError",
    "Params",
    "available_devices",
    "contact_force",
    "rough_lines",
    "run_ensemble",
    "run_specs",
    "step_range",
    "__version__",
]
