"""What an independent reader (mcap's own) makes of a log file: helpers shared by the tests."""
from __future__ import annotations

from mcap.reader import NonSeekingReader


def non_seeking_prefix(path) -> list[int]:
    """Log times of the messages mcap's own non-seeking reader reads before a cut (ns)."""
    prefix = []
    with open(path, 'rb') as stream:
        try:
            for _, _, message in NonSeekingReader(stream).iter_messages(log_time_order=False):
                prefix.append(message.log_time)
        except Exception:                                 # noqa: B902 - the cut-off tail
            pass
    return prefix
