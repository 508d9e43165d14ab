"""What an analysis that changes nothing does to the members' drilling (the write-back's bit force).

    python benchmarks/identity_writes.py [--members 8] [--settle 30] [--duration 30]
                                         [--every 40] [--law-only]

Members of the paper's string with germs at delta = 0.2 and law factors of log-std 0.15 (as
the filter's prior) are stepped ``--settle`` s, then ``--duration`` s twice: once as they are,
once with their analysed state written back unchanged (``MemberState.write(extract())``)
every ``--every`` steps (40: the filter's 5 Hz). The hole's mean rate of each member over
the second part is printed for both, and the jumps of the hole at the writes. With
``--law-only`` the state evaluation reads the law at the bit's velocities
(``NewmarkIntegrator.evaluate(bearing=False)``), which for a bit resting on the compliant
rock's spring is not the force it bears.
"""
from __future__ import annotations

import argparse

import numpy as np

from drill_twin.cli import blas_threads

blas_threads.limit_to_one()

from drill_twin.assimilation.state import MemberState  # noqa: E402
from drill_twin.config import load_config  # noqa: E402
from drill_twin.integrator import newmark  # noqa: E402
from drill_twin.integrator.simulator import Simulator  # noqa: E402
from drill_twin.uncertainty.germ import germs_for_realizations  # noqa: E402


def drilled(config, germs, scales, settle_s, duration_s, every):
    """Return ((m,) the hole's mean rate m/s, (m,) the writes' share m/s) over the second part."""
    members = germs.shape[0]
    sim = Simulator(config, members, germs=germs, law_scales=scales)
    state = MemberState(sim, members, ('axial', 'torsional'), 'law')
    for _ in range(int(round(settle_s / sim.dt))):
        sim.step()
    start = sim.hole_u().copy()
    jumps = np.zeros(members)
    for k in range(1, int(round(duration_s / sim.dt)) + 1):
        sim.step()
        if every and k % every == 0:
            before = sim.hole_u().copy()
            state.write(state.extract())
            jumps += sim.hole_u() - before
    return (sim.hole_u() - start) / duration_s, jumps / duration_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--members', type=int, default=8)
    parser.add_argument('--settle', type=float, default=30.0)
    parser.add_argument('--duration', type=float, default=30.0)
    parser.add_argument('--every', type=int, default=40)
    parser.add_argument('--law-only', action='store_true')
    args = parser.parse_args()
    if args.law_only:
        evaluate = newmark.NewmarkIntegrator.evaluate
        newmark.NewmarkIntegrator.evaluate = (
            lambda self, state, bearing=True: evaluate(self, state, bearing=False))
    config = load_config()
    germs = germs_for_realizations(0.2, 0, range(args.members))
    scales = np.exp(0.15 * np.random.default_rng(2).standard_normal((args.members, 5)))
    plain, _ = drilled(config, germs, scales, args.settle, args.duration, 0)
    written, jumps = drilled(config, germs, scales, args.settle, args.duration, args.every)
    np.set_printoptions(precision=3, suppress=True, linewidth=120)
    evaluation = 'the law at the velocities' if args.law_only else 'the force the rock bears'
    print(f'state evaluation: {evaluation}')
    print('hole rate, mm/s, as stepped:          ', plain * 1e3)
    print(f'hole rate, mm/s, written every {args.every} steps:', written * 1e3)
    print('of which the writes\' jumps, mm/s:     ', jumps * 1e3)
    print(f'largest change: {np.max(np.abs(written - plain)) * 1e3:.3g} mm/s')


if __name__ == '__main__':
    main()
