"""
The default configuration reproduces Table 1 of the paper (MODEL.md's reading).

The reference is Table 1 as printed in Ritto, Soize & Sampaio (2009), copied here by hand
(rank or pair of ranks, eigenfrequency in Hz, type); the package's own copy
(``drill_twin.modal.paper_table1``, which ``drill-twin modes`` prints) is checked against it.
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

from drill_twin.modal.paper_table1 import TABLE1

# Ranks of the lateral pairs living in the drill collars (between stabilizer and bit).
COLLAR_PAIRS = {5, 6, 14, 15}

PRINTED_TABLE1 = """
1–2 0.0372 Lateral
3–4 0.0744 Lateral
5–6 0.1065 Lateral
7–8 0.1117 Lateral
9–10 0.1488 Lateral
11–12 0.1860 Lateral
13 0.2144 Torsional
14–15 0.2160 Lateral
16–17 0.2234 Lateral
18–19 0.2605 Lateral
76 1.1105 Torsional
81 1.2018 Axial
163–164 3.2671 Lateral
165 4.6761 Axial
"""
"""Table 1 of the paper as printed (rows 'Rank Eigenfrequency (Hz) Type'), by hand."""


def _paper_table() -> dict[int, tuple[float, str]]:
    """{rank: (Hz, type)} of the printed table, pairs of ranks expanded."""
    table = {}
    for line in PRINTED_TABLE1.strip().splitlines():
        ranks, frequency, kind = line.split()
        first, _, last = ranks.partition('–')
        for rank in range(int(first), int(last or first) + 1):
            table[rank] = (float(frequency), kind.lower())
    return table


PAPER = _paper_table()


def test_the_package_copy_of_table1_is_the_printed_table():
    """What ``drill-twin modes`` prints as the paper's column is the printed table."""
    assert len(PAPER) == 24
    assert TABLE1 == PAPER


def _by_rank(basis):
    return {int(r): i for i, r in enumerate(basis.rank) if r > 0}


def test_reduced_basis_composition(default_analysis):
    _, _, basis = default_analysis
    assert basis.size == 166
    assert basis.count('lateral') == 158
    assert basis.count('torsional') == 4
    assert basis.count('axial') == 3
    assert basis.rigid_body_modes == 2                 # axial rigid mode + driven rotation
    assert int(np.sum(basis.rigid)) == 1
    assert basis.kind[basis.rigid][0] == 'axial'
    # MODEL.md point 6: ranks 1-164 are every mode up to 3.2671 Hz, rank 165 the 3rd axial.
    by_rank = _by_rank(basis)
    assert basis.kind[by_rank[165]] == 'axial'
    assert max(basis.frequency_hz[by_rank[r]] for r in range(1, 165)) < 3.3
    _, modes, _ = default_analysis
    below = np.sum((modes.frequency_hz < basis.frequency_hz[by_rank[164]] * (1 + 1e-9))
                   & ~modes.rigid)
    assert below == 164


@pytest.mark.parametrize('rank', sorted(PAPER))
def test_table1_entry(default_analysis, rank):
    _, _, basis = default_analysis
    index = _by_rank(basis)[rank]
    paper_hz, paper_type = PAPER[rank]
    assert basis.kind[index] == paper_type
    deviation = basis.frequency_hz[index] / paper_hz - 1
    if paper_type in ('torsional', 'axial'):
        assert abs(deviation) < 0.003
    elif rank in COLLAR_PAIRS:
        # Unexplained, as in MODEL.md: +1.58 % (ranks 5-6) and +1.43 % (ranks 14-15).
        assert 0.010 < deviation < 0.020
    else:
        assert abs(deviation) < 0.01


def test_table1_converges_under_mesh_refinement(default_config):
    """Doubling the elements changes the Table 1 entries less each time."""
    from drill_twin.config import load_config
    from drill_twin.modal.reduced_basis import modal_analysis
    tracked = {}
    for factor in (1, 2, 4):
        config = load_config(None, [f'sections.drill_pipe.elements={32 * factor}',
                                    f'sections.drill_collar.elements={24 * factor}'])
        _, modes, _ = modal_analysis(config)
        elastic = ~modes.rigid
        tracked[factor] = np.concatenate([
            modes.frequency_hz[elastic & (modes.kind == 'torsional')][:2],
            modes.frequency_hz[elastic & (modes.kind == 'axial')][:3],
            modes.frequency_hz[elastic & (modes.kind == 'lateral')][:20:2]])
    first = np.abs(tracked[2] / tracked[1] - 1)
    second = np.abs(tracked[4] / tracked[2] - 1)
    assert np.all(second <= first + 1e-12)
    # Pre-asymptotic: K_g uses the piecewise-constant N of linear axial elements, so the
    # lateral entries converge by a factor 2.2, then 3.0, per halving (4 asymptotically).
    assert np.max(second) < 0.5 * np.max(first)


def test_modes_command_json():
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'modes', '--json'],
                            capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == {'modes', 'rigid_body_modes', 'prestress'}
    assert len(data['modes']) == 165
    assert data['rigid_body_modes'] == 2
    assert {m['type'] for m in data['modes']} == {'lateral', 'torsional', 'axial'}
    assert [m['rank'] for m in data['modes']] == list(range(1, 166))
    assert data['modes'][12]['type'] == 'torsional'
    assert data['modes'][12]['frequency_hz'] == pytest.approx(PAPER[13][0], rel=3e-3)
    assert set(data['prestress']) == {'hook_force_n', 'neutral_point_above_bit_m'}
    assert data['prestress']['hook_force_n'] == pytest.approx(1.0633e6, rel=1e-3)
    assert data['prestress']['neutral_point_above_bit_m'] == pytest.approx(35.6, rel=1e-2)


def test_modes_command_table_shows_the_paper_values():
    command = [sys.executable, '-m', 'drill_twin.cli.main', 'modes', '--count', '20']
    result = subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    rows = [line.split() for line in lines[3:]]
    assert len(rows) == 20
    assert rows[12][:3] == ['13', rows[12][1], 'torsional']
    for rank in range(1, 20):                          # the paper column: Table 1 as printed
        assert rows[rank - 1][3] == f'{PAPER[rank][0]:.4f}'
    assert rows[19][3:] == []                          # rank 20 is not in Table 1
