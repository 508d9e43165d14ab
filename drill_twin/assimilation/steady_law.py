"""
The steady drilling point of a bit-rock law with a germ: ROP and TOB at a bit speed and WOB.

Used to compare an estimated law (the configuration's with the analysed germ) with the
truth's (another configuration, another germ) where it matters: at the operating point.
With the germ, F_1(ROP, omega) = -WOB is solved for ROP by Brent's method on the law's
randomised axial force (:meth:`BitRockLaw.forces`), then TOB = -F_2 there.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from drill_twin.model.bit_rock import BitRockLaw

ROP_BRACKET_M_PER_S = (1e-9, 0.1)
"""Where the steady ROP is searched (m/s)."""


def steady_point(law: BitRockLaw, omega_rad_per_s: float, weight_on_bit_n: float,
                 germ: np.ndarray | None = None) -> tuple[float, float]:
    """
    (ROP m/s, TOB N m > 0) of steady drilling at omega (rad/s) under WOB (N, > 0).

    NaNs if the law cannot drill there (no root in the bracket).
    """
    germs = None if germ is None else np.asarray(germ, dtype=float).reshape(1, 2, 2)

    def axial(rop):
        force, _, lifted = law.forces(np.array([rop]), np.array([omega_rad_per_s]), germs)
        return float(force[0]) + weight_on_bit_n if not lifted[0] else weight_on_bit_n

    low, high = ROP_BRACKET_M_PER_S
    if np.sign(axial(low)) == np.sign(axial(high)):
        return float('nan'), float('nan')
    rop = brentq(axial, low, high, xtol=1e-14, rtol=1e-12)
    _, torque, _ = law.forces(np.array([rop]), np.array([omega_rad_per_s]), germs)
    return float(rop), float(-torque[0])
