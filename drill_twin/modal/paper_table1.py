"""Table 1 of Ritto, Soize & Sampaio (2009): eigenfrequencies of the linearised system."""
from __future__ import annotations

TABLE1: dict[int, tuple[float, str]] = {
    1: (0.0372, 'lateral'), 2: (0.0372, 'lateral'),
    3: (0.0744, 'lateral'), 4: (0.0744, 'lateral'),
    5: (0.1065, 'lateral'), 6: (0.1065, 'lateral'),
    7: (0.1117, 'lateral'), 8: (0.1117, 'lateral'),
    9: (0.1488, 'lateral'), 10: (0.1488, 'lateral'),
    11: (0.1860, 'lateral'), 12: (0.1860, 'lateral'),
    13: (0.2144, 'torsional'),
    14: (0.2160, 'lateral'), 15: (0.2160, 'lateral'),
    16: (0.2234, 'lateral'), 17: (0.2234, 'lateral'),
    18: (0.2605, 'lateral'), 19: (0.2605, 'lateral'),
    76: (1.1105, 'torsional'),
    81: (1.2018, 'axial'),
    163: (3.2671, 'lateral'), 164: (3.2671, 'lateral'),
    165: (4.6761, 'axial'),
}
"""rank -> (frequency in Hz, type), as printed in the paper."""
