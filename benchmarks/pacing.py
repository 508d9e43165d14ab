"""What running every 10 ms instead of back to back costs this machine, for other work.

    python benchmarks/pacing.py [--runs 300] [--sizes 0.25 1 3]

The twin's tick runs once every 10 ms and sleeps in between. On a machine whose caches are
shared with other tenants (a VM), what a tick left in the caches may be gone by the next one,
and the tick then costs more CPU than the same tick run back to back (benchmarks/twin_tick.py
--paced). This benchmark says how much of that is the machine: reference workloads, each run
``--runs`` times back to back and then once every 10 ms of wall time (sleeping in between),
CPU time per run (time.process_time), p50 and p99, and the ratio paced / back to back of the
p50s:

- ``stream S MB``: one pass that scales arrays of S MB in all (a working set of S MB read and
  written once per run, as a tick reads its operators and writes its work arrays);
- ``blas L2``: 60 products of (114 x 79) by (79 x 64), the size of the twin's bending blocks
  at 64 members (operands 160 kB: they fit in this class of core's 512 kB L2);
- ``python``: a loop over a dict of 2000 entries (the interpreter's own working set).

On a dedicated machine, where nothing else evicts the caches, every ratio should be near 1; a
ratio well above 1 for the streams says the machine loses a working set of that size between
two ticks. Single-threaded BLAS.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

PERIOD_S = 0.01
"""Wall time between two paced runs (the node's 100 Hz tick)."""


def stream_workload(megabytes: float, rng: np.random.Generator):
    """Return a run that scales float64 arrays of ``megabytes`` MB in all, in place."""
    count = max(1, round(megabytes * 1e6 / (342 * 64 * 8)))     # arrays of the twin's force's size
    arrays = [rng.standard_normal((342, 64)) for _ in range(count)]

    def run():
        for array in arrays:
            array *= 1.0000001
    return run


def blas_workload(rng: np.random.Generator):
    """Return a run of 60 (114 x 79) by (79 x 64) products (operands 160 kB)."""
    shapes, field, out = (rng.standard_normal((114, 79)), rng.standard_normal((79, 64)),
                          np.empty((114, 64)))

    def run():
        for _ in range(60):
            np.dot(shapes, field, out)
    return run


def python_workload():
    """Return a run of 20 passes over a dict of 2000 entries."""
    table = {k: k for k in range(2000)}

    def run():
        total = 0
        for _ in range(20):
            for value in table.values():
                total += value
        return total
    return run


def cpu_ms(run, runs: int, paced: bool) -> np.ndarray:
    """CPU time of each of ``runs`` runs (ms), back to back or one every PERIOD_S."""
    cpu = np.empty(runs)
    start = time.perf_counter()
    for k in range(runs):
        if paced:
            time.sleep(max(0.0, start + k * PERIOD_S - time.perf_counter()))
        tick = time.process_time()
        run()
        cpu[k] = time.process_time() - tick
    return 1e3 * cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=300)
    parser.add_argument('--sizes', type=float, nargs='+', default=[0.25, 1.0, 3.0],
                        help='working sets of the stream workloads (MB)')
    args = parser.parse_args()
    problem = (f'--runs: must be at least 1, got {args.runs}' if args.runs < 1 else
               f'--sizes: working sets must be positive (MB), got {args.sizes}'
               if not all(size > 0 for size in args.sizes) else None)
    if problem:
        print(f'pacing.py: {problem}', file=sys.stderr)
        sys.exit(2)
    rng = np.random.default_rng(0)
    workloads = [(f'stream {size:g} MB', stream_workload(size, rng)) for size in args.sizes]
    workloads += [('blas L2', blas_workload(rng)), ('python', python_workload())]
    print(f'{"workload":>14}  {"back to back p50 / p99 [ms]":>28}  {"paced p50 / p99 [ms]":>21}  '
          f'{"paced / back to back":>20}')
    with threadpool_limits(limits=1, user_api='blas'):
        for name, run in workloads:
            cpu_ms(run, 20, paced=False)                      # warm-up
            together = cpu_ms(run, args.runs, paced=False)
            paced = cpu_ms(run, args.runs, paced=True)
            b50, b99 = np.percentile(together, [50, 99])
            p50, p99 = np.percentile(paced, [50, 99])
            print(f'{name:>14}  {b50:13.3f} / {b99:<12.3f}  {p50:9.3f} / {p99:<9.3f}  '
                  f'{p50 / b50:20.2f}')


if __name__ == '__main__':
    main()
