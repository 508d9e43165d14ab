"""
The files and directories a command will write, checked before its work starts.

A run of minutes must not end in a traceback because its result cannot be written: every
output option is checked first, and a problem is one line naming the option (UsageError, exit
status 2). A place is writable when a file can be created in it: a probe file is created and
removed at once (permission bits say nothing for root, nor for /proc or a read-only mount).
"""
from __future__ import annotations

import os
from pathlib import Path
import stat
import tempfile
from typing import Iterable

from drill_twin.cli.common import UsageError

PROBE_PREFIX = '.drill-twin-probe-'
"""Name prefix of the probe file created (and removed at once) in an output directory."""


def output_file(option: str, text: str | None, suffixes: Iterable[str] = ()) -> Path | None:
    """
    Return the file ``option`` names if the command can write it at the end, else refuse.

    Refused (UsageError naming ``option``): a suffix not among ``suffixes`` (when given), an
    existing directory, a parent directory that is missing, is a file or cannot be written in, an
    existing file that cannot be written. None for an option not given.
    """
    if text is None:
        return None
    path = Path(text)
    suffixes = tuple(suffixes)
    if suffixes and path.suffix.lower() not in suffixes:
        choices = ', '.join(suffixes[:-1]) + ' or ' if len(suffixes) > 1 else ''
        raise UsageError(f'{option}: {text}: use a {choices}{suffixes[-1]} file name')
    if path.is_dir():
        raise UsageError(f'{option}: {text} is a directory; name a file')
    parent = path.parent
    if not parent.exists():
        raise UsageError(f'{option}: {parent}: no such directory')
    if not parent.is_dir():
        raise UsageError(f'{option}: {parent} is a file, not a directory')
    if path.exists():
        _existing_file_writable(option, path)
    else:
        _directory_writable(option, parent)
    return path


def output_directory(option: str, text: str) -> Path:
    """
    Return the directory ``option`` names if the command can create it and write in it.

    Refused (UsageError naming ``option``): an existing file, a directory that cannot be written
    in, or (for a directory still to be made) a nearest existing ancestor that is a file or cannot
    be written in.
    """
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise UsageError(f'{option}: {text} is a file, not a directory')
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f'{option}: {existing} is a file, not a directory')
    _directory_writable(option, existing)
    return path


def distinct(paths: dict[str, str | os.PathLike | None]) -> None:
    """Refuse two options (``paths``: option -> path, None if not given) naming one file."""
    seen: dict[Path, str] = {}
    for option, path in paths.items():
        if path is None:
            continue
        resolved = Path(path).resolve()
        if resolved in seen:
            raise UsageError(f'{option}: {path} is also {seen[resolved]}; name another file')
        seen[resolved] = option


def _directory_writable(option: str, directory: Path) -> None:
    try:
        handle, probe = tempfile.mkstemp(prefix=PROBE_PREFIX, dir=directory)
    except OSError as error:
        raise UsageError(f'{option}: cannot create a file in {directory} '
                         f'({error.strerror or error})') from None
    os.close(handle)
    os.unlink(probe)


def _existing_file_writable(option: str, path: Path) -> None:
    """Open a regular file for appending (nothing written); others (a device) by permission."""
    if not stat.S_ISREG(path.stat().st_mode):
        if not os.access(path, os.W_OK):
            raise UsageError(f'{option}: {path}: cannot be written')
        return
    try:
        with open(path, 'ab'):
            pass
    except OSError as error:
        raise UsageError(f'{option}: {path}: cannot be written ({error.strerror or error})'
                         ) from None
