"""``drill-twin modes``: the eigenfrequencies of the prestressed string, like Table 1."""
from __future__ import annotations

import argparse
import json
import time

from drill_twin.cli.common import (UsageError, add_config_arguments, build_model_or_refuse,
                                   config_from_args)
from drill_twin.modal.paper_table1 import TABLE1


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'modes', help='normal modes of the prestressed string (Table 1)',
        description='Solve the eigenproblem of the linearised, prestressed string (Eq. 32) '
                    'and list the modes of the reduced basis with the paper\'s Table 1.')
    add_config_arguments(parser)
    parser.add_argument('--count', type=int, metavar='N',
                        help='list only the first N modes (default: the whole reduced basis)')
    parser.add_argument('--json', action='store_true', help='print JSON instead of a table')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.count is not None and args.count < 1:
        raise UsageError(f'--count: must be at least 1, got {args.count}')
    config = config_from_args(args)
    start = time.perf_counter()
    model, basis = build_model_or_refuse(config, args.overrides)
    elapsed = time.perf_counter() - start
    elastic = [i for i in range(basis.size) if not basis.rigid[i]]
    if args.count is not None:
        elastic = elastic[:args.count]
    prestress = model.prestress
    if args.json:
        print(json.dumps({
            'modes': [{'rank': int(basis.rank[i]),
                       'frequency_hz': float(basis.frequency_hz[i]),
                       'type': str(basis.kind[i])} for i in elastic],
            'rigid_body_modes': basis.rigid_body_modes,
            'prestress': {'hook_force_n': prestress.hook_load_n,
                          'neutral_point_above_bit_m': prestress.neutral_point_above_bit_m},
        }, indent=2))
        return 0
    neutral = prestress.neutral_point_above_bit_m
    neutral_text = 'none (no compression)' if neutral is None else f'{neutral:.2f} m above the bit'
    print(f'Normal modes of the prestressed string ({config.source})')
    print(f'hook load {prestress.hook_load_n / 1e3:.1f} kN, neutral point {neutral_text}, '
          f'{basis.rigid_body_modes} rigid-body modes; '
          f'basis: {basis.count("lateral")} lateral, {basis.count("torsional")} torsional, '
          f'{basis.count("axial")} axial; solved in {elapsed:.2f} s')
    print(f'{"rank":>5} {"frequency_hz":>13}  {"type":<10} {"paper_hz":>9} {"deviation":>10}')
    for i in elastic:
        rank = int(basis.rank[i])
        line = f'{rank:>5} {basis.frequency_hz[i]:>13.4f}  {basis.kind[i]:<10}'
        if rank in TABLE1:
            paper_hz, paper_type = TABLE1[rank]
            deviation = 100.0 * (basis.frequency_hz[i] / paper_hz - 1.0)
            mark = '' if paper_type == basis.kind[i] else f'  (paper: {paper_type})'
            line += f' {paper_hz:>9.4f} {deviation:>+9.2f}%{mark}'
        print(line)
    return 0
