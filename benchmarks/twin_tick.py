"""CPU time of a twin tick: the mean model and an ensemble in one process.

    python benchmarks/twin_tick.py [--members 64] [--time-step 0.005] [--ticks 300] [--paced]

Builds the twin engine (drill_twin.twin.engine, the ensemble in this process) at the given
time step, takes a tick's steps (10 ms of model time, as the node's 100 Hz timer does) 20
times to warm up, then ``--ticks`` times, and prints the start-up time and the CPU time per
tick (mean, p50, p99, max) with the share of the 10 ms tick budget. CPU time
(time.process_time) is what the budget is about; ``cpu/wall`` says how much of a core the
process got (below 1 on a loaded machine). Ticks follow each other back to back, or with
``--paced`` one every 10 ms of wall time as in the node at real-time pacing (the process
sleeps in between; on this VM a paced tick cost 2-40 % more than back to back in alternating
runs).
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

TICK_S = 0.01
"""Model time of a tick (the node's 100 Hz timer)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--members', type=int, default=64)
    parser.add_argument('--time-step', type=float, default=0.005)
    parser.add_argument('--ticks', type=int, default=300)
    parser.add_argument('--paced', action='store_true',
                        help='one tick every 10 ms of wall time (sleeping in between)')
    args = parser.parse_args()
    start_cpu, start_wall = time.process_time(), time.perf_counter()
    from drill_twin.config import load_config
    from drill_twin.twin.engine import TwinEngine
    from drill_twin.twin.ensemble import EnsembleSettings
    with threadpool_limits(limits=1, user_api='blas'):
        config = load_config(None, [f'integration.time_step_s={args.time_step!r}'])
        engine = TwinEngine(config, EnsembleSettings(members=args.members, dispersion=0.01,
                                                     seed=3))
        steps = max(1, int(round(TICK_S / args.time_step)))
        engine.advance(steps)
        print(f'start to the first tick (imports included): CPU '
              f'{time.process_time() - start_cpu:.2f} s, wall '
              f'{time.perf_counter() - start_wall:.2f} s')
        for _ in range(20):
            engine.advance(steps)
        cpu = np.empty(args.ticks)
        wall = time.perf_counter()
        for k in range(args.ticks):
            if args.paced:                          # the next 10 ms boundary of wall time
                time.sleep(max(0.0, wall + k * TICK_S - time.perf_counter()))
            tick = time.process_time()
            engine.advance(steps)
            cpu[k] = time.process_time() - tick
        wall = time.perf_counter() - wall
        engine.close()
    ms = 1e3 * cpu
    p99 = np.percentile(ms, 99)
    print(f'mean model + {args.members} members, {1e3 * args.time_step:g} ms step, {steps} '
          f'step(s) per tick, {args.ticks} ticks {"paced" if args.paced else "back to back"}: '
          f'CPU per tick mean {ms.mean():.2f} ms, p50 '
          f'{np.percentile(ms, 50):.2f}, p99 {p99:.2f} ({p99 / (1e3 * TICK_S):.0%} of the '
          f'budget), max {ms.max():.2f}; cpu/wall {cpu.sum() / wall:.2f}')


if __name__ == '__main__':
    main()
