"""A corrected low-band law: the thesis's eq 58 plateau divided by its convention factor.

Under mdroll's PSD convention (physics.md section 6) the thesis's plateau (eq 58)

    C_F0 = 1.3 E*^2 R^2 h0^4 (0.277 + H)^2 / (a^2 q_min)

is about ``CONVENTION_FACTOR`` times the measured q -> 0 level of the force PSD (mdroll validate's
"eq 58 factor" check). This package's approximation of the low band, for q well below q_min,
keeps eq 58's scaling, divides by that factor and adds the cos^2(q a) dip of the contact's two
edges (physics.md section 7).
"""

import numpy as np

from mdroll import physics

#: eq 58 over the measured plateau (mdroll validate, H200 full run: 9.55).
CONVENTION_FACTOR = 9.6


def low_band_psd(q, params):
    """C_F(q) (N^2 m) at q (rad/m), q << q_min: eq 58 / CONVENTION_FACTOR x cos^2(q a)."""
    p = params
    plateau = physics.force_psd_plateau_thesis(p.E_star, p.R, p.h0, p.H, p.a, p.q_min)
    return plateau / CONVENTION_FACTOR * np.cos(np.asarray(q) * p.a) ** 2
