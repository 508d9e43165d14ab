"""The bit-rock interaction law (paper Eq. 24-26) and the rock under the bit."""
from __future__ import annotations

from dataclasses import dataclass
import math

from drill_twin.config.bounds import WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON
from drill_twin.config.checks import at_most, ConfigValueError, non_negative, positive


@dataclass(frozen=True, slots=True, kw_only=True)
class BitRock:
    """The bit-rock law of Eq. 24-26 and the static bit reaction of the prestress."""

    a1_m_per_s: float
    a2_m_per_n_s: float
    a3_m_per_rad: float
    a4_n_rad: float
    a5_n_m: float
    regularization_rad_per_s: float
    static_weight_on_bit_n: float
    random_law_rop_scale_m_per_s: float = 1e-4
    """Near ROP = 0 the random law is blended into the mean law over this ROP scale."""
    contact_stiffness_n_per_m: float | None = None
    """The rock's contact stiffness under the bit (not in the paper): the bit resting on bottom
    presses the rock elastically by f / k, and a landing is stopped by that spring instead of
    within one time step. None: a rigid rock (the law alone)."""

    def __post_init__(self):
        positive(self, 'a2_m_per_n_s', 'regularization_rad_per_s',
                 'random_law_rop_scale_m_per_s')
        if self.contact_stiffness_n_per_m is not None:
            positive(self, 'contact_stiffness_n_per_m')
        non_negative(self, 'a1_m_per_s', 'a3_m_per_rad', 'a4_n_rad', 'a5_n_m')
        if not math.isfinite(self.static_weight_on_bit_n):
            raise ConfigValueError('static_weight_on_bit_n', 'must be finite')
        at_most(self, 'static_weight_on_bit_n', WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON)
