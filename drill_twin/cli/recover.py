"""``drill-twin recover``: rewrite a cut MCAP file (killed twin, full disk) into a whole one."""
from __future__ import annotations

import argparse
from pathlib import Path

from drill_twin.cli.common import UsageError
from drill_twin.cli.output_paths import output_file


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'recover', help='rewrite a cut MCAP log file into a complete one',
        description='Copy every message of the complete chunks of an MCAP file that was cut '
                    'short (the twin was killed, or the disk filled) into a new file with a '
                    'summary and footer, which indexed readers (mcap, mcap_ros2, rosbag2, '
                    'rosbags, rerun) open; as `mcap recover` or `ros2 bag reindex`.')
    parser.add_argument('log', metavar='LOG.mcap', help='the cut (or any) MCAP file')
    parser.add_argument('--out', metavar='FIXED.mcap', required=True,
                        help='the complete file to write (not LOG.mcap itself)')
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    source = Path(args.log)
    if not source.is_file():
        raise UsageError(f'{source}: no such file' if not source.exists()
                         else f'{source}: not a file (recover one split of a bag)')
    destination = Path(args.out)
    if destination.exists() and destination.resolve() == source.resolve():
        raise UsageError(f'--out: {destination} is the input file; write elsewhere')
    output_file('--out', args.out)
    from drill_twin.recording.reader import is_complete, NotMcapError, require_mcap
    from drill_twin.recording.recovery import recover_log

    try:
        require_mcap(source)
    except NotMcapError as error:
        raise UsageError(str(error)) from None
    count = recover_log(source, destination)
    state = 'complete already' if is_complete(source) else 'cut short'
    print(f'recovered {count} messages from {source} ({state}) into {destination}')
    return 0
