"""The speed of the time loop on this machine, with the dense-product rate measured alongside.

    python benchmarks/run_all.py [--seconds S] [--members 1 16 64 256] [--simulate S]
                                 [--ticks N]

For the default (paper-fidelity) model and each batch size m it prints: the real-time factor
(simulated seconds per wall second), member-seconds per wall second (m x RTF), force
evaluations per step, the rate of a dense 342 x 166 x m float64 product measured just before
and after that batch (GFLOP/s, single-threaded BLAS like the time loop) and the fraction of
that matrix-product limit the batch reaches: the time its dense products would take at that
rate over the time its steps took. The dense products of one force evaluation are the ones
the loop does (block by block): u = Phi q and the rates and accelerations the forces need,
Phi^T f, and the Newmark residual's C_r v and S0^-1 r (2 m flops per multiply-add). Last, the
RTF that ``drill-twin simulate`` reports (its own loop, recording included), run as a command
three times (its loop of 20 s of model time lasts about half a second, and the same code's
speed moves by 15-30 % from process to process on this VM: one run says little), and the CPU
time of the twin's tick, mean model and 64 members in one process
(``benchmarks/twin_tick.py``: p50, p99 against the 10 ms budget), back to back and paced (one
tick every 10 ms, as the node runs them: on this VM a paced tick costs 1.3-3 times as much
CPU, its working set gone from the caches by the next tick), and what pacing costs the
machine for reference workloads that are not the twin (``benchmarks/pacing.py``: it should be
near 1 on a dedicated machine).

On a shared machine the absolute figures move with the load; the matrix rate measured in the
same run and the fractions say how much. A virtual machine can also slow down by up to half
for periods of seconds to minutes while its load average stays near zero and no steal time
shows (on the 2-core VM of docs/SPEED.md a fixed pure-Python loop takes 5.4 ms or 10.7 ms in
consecutive blocks of one process, the mean model's step 121 or 212 us with it, and
memory-bound references track the step no better, correlation 0.2-0.7): each batch is
therefore timed in BLOCKS blocks and its RTF given over all of them (what a user gets), for
the median block and for the fastest block (the code's speed on a quiet machine, as timeit's
best of repeats).
"""
from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.modal.reduced_basis import modal_analysis

SIMULATE_RUNS = 3
"""Runs of ``drill-twin simulate`` (each a process of its own)."""
BLOCKS = 10
"""Blocks a batch's timed steps are split into (timed each)."""
MATRIX_ROWS, MATRIX_COLUMNS = 342, 166
"""The dense product of the yardstick: the paper model's field-wise DOFs by its reduced
coordinates."""


def matrix_rate(members: int, seconds: float = 0.3) -> float:
    """GFLOP/s of a (342 x 166) by (166 x members) float64 product, best of repeated runs."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(MATRIX_ROWS, MATRIX_COLUMNS))
    b = rng.normal(size=(MATRIX_COLUMNS, members))
    out = np.empty((MATRIX_ROWS, members))
    np.matmul(a, b, out=out)
    repeats = max(1, int(2e7 / (MATRIX_ROWS * MATRIX_COLUMNS * members)))
    best = np.inf
    deadline = time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        start = time.perf_counter()
        for _ in range(repeats):
            np.matmul(a, b, out=out)
        best = min(best, (time.perf_counter() - start) / repeats)
    return 2.0 * MATRIX_ROWS * MATRIX_COLUMNS * members / best / 1e9


def dense_flops_per_evaluation(system) -> float:
    """Flops of the dense products of one force evaluation, per member (module docstring)."""
    b = system.blocks
    blocks = sum(block.shapes.size for block in b.values())      # Phi q or Phi^T f
    rates = (2 * b['torsional'].shapes.size + 2 * b['bending_y'].shapes.size
             + b['bending_z'].shapes.size + b['axial'].shapes.shape[1])
    newmark = 2 * system.size ** 2
    return 2.0 * (2 * blocks + rates + newmark)


def measure_batch(config, system, members: int, seconds: float) -> dict:
    """
    Time ``seconds`` of model time of a batch, in BLOCKS blocks.

    Returns the RTF and rates over all blocks, and the RTF of the median and of the fastest
    block (wall clock).
    """
    simulator = Simulator(config, members=members, system=system)
    for _ in range(20):                                   # warm-up (and the kernels' load)
        simulator.step()
    steps = max(BLOCKS, int(round(seconds / simulator.dt / BLOCKS))) * BLOCKS
    counters = simulator.integrator.counters
    evaluations = counters.force_evaluations
    rate_before = matrix_rate(members)
    blocks = []
    for _ in range(BLOCKS):
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(steps // BLOCKS):
            simulator.step()
        blocks.append((time.perf_counter() - start, time.process_time() - cpu))
    wall, cpu = (sum(b[0] for b in blocks), sum(b[1] for b in blocks))
    rate_after = matrix_rate(members)
    per_step = (counters.force_evaluations - evaluations) / steps
    rate = 0.5 * (rate_before + rate_after)
    limit = dense_flops_per_evaluation(system) * members * per_step * steps / (rate * 1e9)
    simulated = steps * simulator.dt
    return {'members': members, 'rtf': simulated / wall, 'member_rtf': members * simulated / wall,
            'cpu_rtf': simulated / cpu, 'member_cpu_rtf': members * simulated / cpu,
            'evaluations_per_step': per_step, 'gflops': rate, 'fraction': limit / cpu,
            'cpu_share': cpu / wall, 'step_cpu_ms': 1e3 * cpu / steps,
            'median_block_rtf': simulated / BLOCKS / float(np.median([b[0] for b in blocks])),
            'best_block_rtf': simulated / BLOCKS / min(b[0] for b in blocks)}


def simulate_command(seconds: float) -> tuple[float, float, float]:
    """(RTF printed by ``drill-twin simulate --duration seconds``, wall time and CPU time of
    the command)."""
    with tempfile.TemporaryDirectory() as folder:
        start, cpu = time.perf_counter(), os.times()
        out = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'simulate',
                              '--duration', str(seconds), '--out',
                              os.path.join(folder, 'run.npz')],
                             capture_output=True, text=True, check=True)
        wall, end = time.perf_counter() - start, os.times()
    match = re.search(r'real-time factor ([0-9.]+)', out.stdout)
    child_cpu = (end.children_user - cpu.children_user) + (end.children_system
                                                           - cpu.children_system)
    return float(match.group(1)), wall, child_cpu


def benchmark_lines(script: str, *arguments: str) -> list[str]:
    """The lines ``benchmarks/<script> arguments`` prints, run in a process of its own."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), script)
    out = subprocess.run([sys.executable, path, *arguments], capture_output=True, text=True,
                         check=True)
    return out.stdout.strip().splitlines()


def twin_tick_command(ticks: int, paced: bool = False) -> str:
    """The summary line of ``benchmarks/twin_tick.py --ticks ticks [--paced]`` (own process)."""
    return benchmark_lines('twin_tick.py', '--ticks', str(ticks),
                           *(['--paced'] if paced else []))[-1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=5.0,
                        help='simulated seconds per batch size (default 5)')
    parser.add_argument('--members', type=int, nargs='+', default=[1, 16, 64, 256])
    parser.add_argument('--simulate', type=float, default=20.0, metavar='S',
                        help='duration of the drill-twin simulate run (0: skip; default 20)')
    parser.add_argument('--ticks', type=int, default=500,
                        help='twin ticks of benchmarks/twin_tick.py (0: skip; default 500)')
    args = parser.parse_args()
    config = load_config()
    print(f'{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {platform.node()}, '
          f'{platform.processor() or platform.machine()}, {os.cpu_count()} cores, '
          f'load average {os.getloadavg()[0]:.2f}')
    with threadpool_limits(limits=1, user_api='blas'):
        model, _, basis = modal_analysis(config)
        system = build_reduced_system(model, basis)
        print(f'paper model: {system.n_dofs} field-wise DOFs, {system.size} reduced '
              f'coordinates, time step {1e3 * config.integration.time_step_s:g} ms; '
              f'{dense_flops_per_evaluation(system) / 1e3:.0f} kflop of dense products per '
              f'member and force evaluation')
        print('RTF and member-seconds per second of wall-clock time / of CPU time; step: CPU '
              'time per step')
        print(f'{"members":>7} {"RTF wall":>9} {"RTF cpu":>8} {"member-s/s wall":>16} '
              f'{"member-s/s cpu":>15} {"step ms":>8} {"evals/step":>10} {"matmul GF/s":>12} '
              f'{"of limit":>9} {"cpu/wall":>9}')
        results = []
        for members in args.members:
            r = measure_batch(config, system, members, args.seconds)
            results.append(r)
            print(f'{members:>7} {r["rtf"]:>9.2f} {r["cpu_rtf"]:>8.2f} {r["member_rtf"]:>16.1f} '
                  f'{r["member_cpu_rtf"]:>15.1f} {r["step_cpu_ms"]:>8.3f} '
                  f'{r["evaluations_per_step"]:>10.2f} {r["gflops"]:>12.1f} '
                  f'{100 * r["fraction"]:>8.1f}% {r["cpu_share"]:>9.2f}', flush=True)
        print(f'RTF by block ({BLOCKS} blocks a batch, wall clock): median / fastest')
        for r in results:
            print(f'{r["members"]:>7} {r["median_block_rtf"]:>8.2f} / {r["best_block_rtf"]:>7.2f}'
                  f'  member-s/s {r["members"] * r["median_block_rtf"]:>7.1f} / '
                  f'{r["members"] * r["best_block_rtf"]:>7.1f}')
    if args.simulate > 0:
        runs = [simulate_command(args.simulate) for _ in range(SIMULATE_RUNS)]
        rtfs = ' / '.join(f'{r[0]:.2f}' for r in runs)
        median = float(np.median([r[0] for r in runs]))
        wall, cpu = np.median([r[1:] for r in runs], axis=0)
        print(f'drill-twin simulate --duration {args.simulate:g}, {SIMULATE_RUNS} runs: '
              f'real-time factor {rtfs} (median {median:.2f}; its loop, wall clock); a command '
              f'took {wall:.1f} s wall, {cpu:.1f} s CPU (medians, start-up included)')
    if args.ticks > 0:
        for paced in (False, True):
            print(f'twin tick (benchmarks/twin_tick.py{" --paced" if paced else ""}, one '
                  f'process): {twin_tick_command(args.ticks, paced)}')
        print('what running every 10 ms costs this machine for work that is not the twin '
              '(benchmarks/pacing.py, CPU time per run):')
        for line in benchmark_lines('pacing.py'):
            print(f'  {line}')
    print(f'load average at the end {os.getloadavg()[0]:.2f}')


if __name__ == '__main__':
    main()
