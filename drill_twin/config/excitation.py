"""Sources of excitation that real strings have and the paper leaves out (off by default)."""
from __future__ import annotations

from dataclasses import dataclass, field

from drill_twin.config.bounds import (
    ECCENTRICITY_MAX_M, ECCENTRICITY_REASON, IMBALANCE_MASS_MAX_KG, IMBALANCE_MASS_REASON,
    LENGTH_MAX_M, LENGTH_REASON, LOBE_AMPLITUDE_MAX_M, LOBE_AMPLITUDE_REASON, LOBES_MAX,
    LOBES_REASON)
from drill_twin.config.checks import at_most, ConfigValueError, non_negative


@dataclass(frozen=True, slots=True, kw_only=True)
class Imbalance:
    """
    A mass imbalance or bent-collar eccentricity at one node of the string.

    The mass ``mass_kg`` (already part of the string's mass) has its centre at
    ``eccentricity_m`` from the section's axis, in the direction fixed to the section that is
    at angle theta_x (the local spin angle of the node, top-drive angle plus elastic twist) from
    the y axis. It loads the node with m e (theta_x'^2 cos + theta_x'' sin,
    theta_x'^2 sin - theta_x'' cos) on (v, w) and m e (v'' sin - w'' cos) - m e^2 theta_x''
    on theta_x (docs/LATERAL.md). Applied at the mesh node nearest ``position_m`` (m, down
    from the top).
    """

    enabled: bool = False
    position_m: float = 1500.0
    mass_kg: float = 0.0
    eccentricity_m: float = 0.0

    def __post_init__(self):
        non_negative(self, 'position_m', 'mass_kg', 'eccentricity_m')
        at_most(self, 'mass_kg', IMBALANCE_MASS_MAX_KG, IMBALANCE_MASS_REASON)
        at_most(self, 'eccentricity_m', ECCENTRICITY_MAX_M, ECCENTRICITY_REASON)
        at_most(self, 'position_m', LENGTH_MAX_M, LENGTH_REASON)

    @property
    def unbalance_kg_m(self) -> float:
        """Return m e (kg m); zero when disabled."""
        return self.mass_kg * self.eccentricity_m if self.enabled else 0.0


@dataclass(frozen=True, slots=True, kw_only=True)
class BottomHolePattern:
    """
    A lobed hole bottom: the rock's surface under the bit rises and falls as the bit turns.

    The undeformed bottom under the bit lies ``amplitude_m`` sin(``lobes`` phi) below the
    hole's mean bottom, phi the bit's spin angle (top-drive angle plus the bit's twist): the
    surface a roller-cone bit cuts (three lobes), the classic axial excitation of bit bounce
    (docs/LATERAL.md, "A lobed hole bottom: bit bounce"). The bit-rock law sets the bit's
    velocity relative to that surface. Needs a compliant rock
    (``bit_rock.contact_stiffness_n_per_m``).
    """

    enabled: bool = False
    lobes: int = 3
    amplitude_m: float = 0.0

    def __post_init__(self):
        if isinstance(self.lobes, bool) or not isinstance(self.lobes, int) or self.lobes < 1:
            raise ConfigValueError('lobes', f'must be a whole number >= 1, got {self.lobes!r}')
        at_most(self, 'lobes', LOBES_MAX, LOBES_REASON)
        non_negative(self, 'amplitude_m')
        at_most(self, 'amplitude_m', LOBE_AMPLITUDE_MAX_M, LOBE_AMPLITUDE_REASON)

    @property
    def height_m(self) -> float:
        """Return the lobes' amplitude (m); zero when disabled."""
        return self.amplitude_m if self.enabled else 0.0


@dataclass(frozen=True, slots=True, kw_only=True)
class Excitation:
    """Sources of excitation outside the paper's model (all off by default)."""

    imbalance: Imbalance = field(default_factory=Imbalance)
    bottom_hole_pattern: BottomHolePattern = field(default_factory=BottomHolePattern)
