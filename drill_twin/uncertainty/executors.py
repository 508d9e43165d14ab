"""Where the chunks of a study run: this process, local processes, or a Dask cluster.

Every executor yields the results of ``function(*arguments)`` for each argument tuple, in
completion order; the study sorts them by realization index, so the results do not depend
on the executor.
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed


class SerialExecutor:
    """Run every chunk here, one after the other."""

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
                                         mp_context=multiprocessing.get_context('spawn'))

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
    """Dask if a scheduler address is given, else local processes (serial for 1 worker)."""
    if scheduler:
        return DaskExecutor(scheduler)
    workers = workers or multiprocessing.cpu_count()
    return SerialExecutor() if workers <= 1 else LocalProcessExecutor(workers)
