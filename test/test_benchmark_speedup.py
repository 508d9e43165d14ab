"""benchmarks/speedup.py reads the table benchmarks/realtime_factor.py prints (their contract)."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _speedup():
    spec = importlib.util.spec_from_file_location('speedup', ROOT / 'benchmarks' / 'speedup.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_speedup_reads_every_batch_size_of_the_realtime_factor_table():
    output = subprocess.run(
        [sys.executable, 'benchmarks/realtime_factor.py', '--seconds', '0.05',
         '--members', '1', '2'], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    factors = _speedup().realtime_factors(output)
    assert set(factors) == {1, 2}
    rows = {int(line.split()[0]): [float(x) for x in line.split()]
            for line in output.splitlines() if line.split()[:1] in (['1'], ['2'])}
    for members, rtf in factors.items():                 # the RTF column, not another one
        _, _, wall_per_simulated, _, member_rtf, _ = rows[members]
        assert rtf > 0 and abs(members * rtf - member_rtf) <= 0.051
        assert abs(rtf * wall_per_simulated - 1.0) <= 0.0005 * rtf + 1e-3
    # The header, the set-up line and anything else are not rows.
    assert _speedup().realtime_factors('members dt RTF\ndefault model: 342 DOFs\n') == {}
