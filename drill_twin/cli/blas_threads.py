"""
One BLAS thread per process, set before numpy is imported.

The reduced model's matrices are small (166 coordinates, 64 members): OpenBLAS's threads cost
more than they give, and where the twin's processes already share the cores the threads spin
against each other. The ensemble worker and the Monte Carlo workers already limit themselves
(threadpoolctl); the node's own process, the in-process ensemble and the offline commands are
limited here. On a 2-core VM beside another twin, two steps of the mean model and of 64
members at delta 0.1 and WOB 300 kN in one process take 36 ms of CPU with
OpenBLAS's default two threads, 6.6 ms with one; the state guard's products alone 2.3 ms
against 0.39 ms. A value already set in the environment is kept.
"""
from __future__ import annotations

import os

VARIABLES = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')


def limit_to_one() -> None:
    """Ask for one BLAS thread (inherited by worker processes), unless the user chose."""
    for name in VARIABLES:
        os.environ.setdefault(name, '1')
