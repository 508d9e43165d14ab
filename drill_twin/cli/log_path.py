"""The LOG argument of ``view``, ``replay`` and ``recover``: a bag directory or an MCAP file."""
from __future__ import annotations

from pathlib import Path

from drill_twin.cli.common import UsageError

HELP = 'a twin log: its bag directory (metadata.yaml and MCAP splits) or one .mcap file'


def existing_log(text: str) -> Path:
    """
    Return ``text`` as a path to a readable log; UsageError (one line) if it is not one.

    Not one: missing, a directory without MCAP files, a file (or a listed split) that is not
    MCAP.
    """
    from drill_twin.recording.reader import log_files, NotMcapError

    path = Path(text)
    try:
        log_files(path)
    except FileNotFoundError as error:
        raise UsageError(str(error.args[0] if error.args else error)) from None
    except NotMcapError as error:
        raise UsageError(str(error)) from None
    except (OSError, ValueError) as error:
        raise UsageError(f'{path}: {error}') from None
    return path
