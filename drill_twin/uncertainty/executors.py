"""
Where the chunks of a study run: this process, local processes, or a Dask cluster.

Every executor yields the results of ``function(*arguments)`` for each argument tuple, in
completion order; the study sorts them by realization index, so the results do not depend
on the executor.

Bitwise reproducibility. A chunk computes the same numbers wherever it runs provided the
BLAS library is set up the same way: local worker processes start with the single-threaded
BLAS environment that Dask's nanny gives its workers, so a study is identical bit for bit
with 1 or W local workers or a Dask cluster on the same machine. Machines whose CPUs make
BLAS choose other kernels agree to rounding (about 1e-15), which the dynamics do not amplify
(tests: about 1e-13 after 40 s).

Dask's ``distributed`` (a second and a half to import) is imported by :class:`DaskExecutor`
alone, when a study is given a scheduler's address.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed

SINGLE_THREADED_BLAS = {'OMP_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1',
                        'OPENBLAS_NUM_THREADS': '1'}
"""What distributed's nanny sets for its workers (distributed.nanny.pre-spawn-environ)."""


def _worker_environment():
    """Process initializer: runs before numpy is imported in a spawned worker."""
    os.environ.update(SINGLE_THREADED_BLAS)


class SerialExecutor:
    """
    Run every chunk in this process, one after the other.

    Agrees with the others to rounding: this process's BLAS was set up before the study.
    """

    workers = 1

    def run(self, function, arguments):
        for args in arguments:
            yield function(*args)

    def close(self):
        pass


class LocalProcessExecutor:
    """A pool of ``workers`` spawned processes on this machine."""

    def __init__(self, workers: int):
        self.workers = workers
        self._pool = ProcessPoolExecutor(max_workers=workers,
                                         mp_context=multiprocessing.get_context('spawn'),
                                         initializer=_worker_environment)

    def run(self, function, arguments):
        futures = [self._pool.submit(function, *args) for args in arguments]
        for future in as_completed(futures):
            yield future.result()

    def close(self):
        self._pool.shutdown(cancel_futures=True)


class DaskExecutor:
    """The workers of a Dask distributed scheduler at ``address`` (e.g. tcp://host:8786)."""

    def __init__(self, address: str):
        from distributed import Client

        self.address = address
        self._client = Client(address, timeout='30s')
        self.workers = max(1, len(self._client.scheduler_info().get('workers', {})))

    def run(self, function, arguments):
        from distributed import as_completed as dask_as_completed

        futures = [self._client.submit(function, *args, pure=False) for args in arguments]
        for future in dask_as_completed(futures):
            yield future.result()

    def close(self):
        self._client.close()


def make_executor(workers: int | None, scheduler: str | None):
    """
    Make a Dask executor if a scheduler address is given, else ``workers`` local processes.

    ``workers`` defaults to one per core; even one worker runs in its own process, for
    identical BLAS set-up.
    """
    if scheduler:
        return DaskExecutor(scheduler)
    return LocalProcessExecutor(max(1, workers or multiprocessing.cpu_count()))
