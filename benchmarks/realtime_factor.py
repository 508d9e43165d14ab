"""Real-time factor of the mean model and of batches (targets: docs/SPEED.md).

    python benchmarks/realtime_factor.py [--seconds S] [--members 1 16 64]

Prints, for the default (paper-fidelity) model and each batch size: the time step, wall time
per simulated second, the real-time factor (simulated seconds per wall second), force
evaluations per step, and the assembly/modal set-up time. Runs with single-threaded BLAS,
as the simulation runner does.
"""
from __future__ import annotations

import argparse
import time

from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.modal.reduced_basis import modal_analysis


def measure(config, system, members: int, seconds: float) -> dict:
    simulator = Simulator(config, members=members, system=system)
    for _ in range(20):                                    # warm-up
        simulator.step()
    steps = int(round(seconds / simulator.dt))
    counters = simulator.integrator.counters
    evaluations_before = counters.force_evaluations
    start = time.perf_counter()
    for _ in range(steps):
        simulator.step()
    wall = time.perf_counter() - start
    simulated = steps * simulator.dt
    return {'members': members, 'time_step_s': simulator.dt,
            'wall_per_simulated_s': wall / simulated, 'real_time_factor': simulated / wall,
            'evaluations_per_step': (counters.force_evaluations - evaluations_before) / steps}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=20.0, help='simulated seconds per case')
    parser.add_argument('--members', type=int, nargs='+', default=[1, 16, 64])
    args = parser.parse_args()
    config = load_config()
    with threadpool_limits(limits=1, user_api='blas'):
        start = time.perf_counter()
        model, _, basis = modal_analysis(config)
        system = build_reduced_system(model, basis)
        setup = time.perf_counter() - start
        print(f'default model: {model.n_dofs} DOFs, {system.size} reduced coordinates; '
              f'assembly + modes + reduced operators {setup:.2f} s')
        print(f'{"members":>8} {"dt [ms]":>8} {"wall/sim s":>11} {"RTF":>7} {"member-RTF":>11} '
              f'{"evals/step":>11}')
        for members in args.members:
            r = measure(config, system, members, args.seconds)
            print(f'{members:>8} {1e3 * r["time_step_s"]:>8.2f} '
                  f'{r["wall_per_simulated_s"]:>11.3f} {r["real_time_factor"]:>7.2f} '
                  f'{members * r["real_time_factor"]:>11.1f} '
                  f'{r["evaluations_per_step"]:>11.2f}')


if __name__ == '__main__':
    main()
