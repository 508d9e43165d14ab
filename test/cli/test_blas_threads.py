"""The command line runs BLAS on one thread per process unless the user chose otherwise."""
from __future__ import annotations

import os
import subprocess
import sys

from conftest import REPO

PROBE = '''
import drill_twin.cli.main
import numpy
from threadpoolctl import threadpool_info
print(max(i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'))
'''


def _blas_threads(env) -> int:
    result = subprocess.run([sys.executable, '-c', PROBE], capture_output=True, text=True,
                            cwd=REPO, env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    return int(result.stdout.strip())


def test_the_command_line_asks_for_one_blas_thread():
    env = {k: v for k, v in os.environ.items()
           if k not in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')}
    assert _blas_threads(env) == 1


def test_a_thread_count_the_user_set_is_kept():
    env = {k: v for k, v in os.environ.items() if k not in ('OMP_NUM_THREADS', 'MKL_NUM_THREADS')}
    env['OPENBLAS_NUM_THREADS'] = '2'
    assert _blas_threads(env) == 2
