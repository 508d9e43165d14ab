"""The ROS domain ids a pytest process claims (conftest.claim_domain_block), without ROS.

Two ``make test`` runs at once must not share a domain: each pytest process (each xdist
worker) claims a block of ids by a lock file held for its life. Here the claims are made by
child processes on a small pool in a folder of the test's own.
"""
from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import claim_domain_block, DOMAIN_IDS, DOMAIN_PURPOSES, REPO, session_domain_id

POOL = range(10, 18)                    # two blocks of four
CLAIM = '''
import sys
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from conftest import claim_domain_block
ids, lock = claim_domain_block(4, range(10, 18), Path(sys.argv[2]))
print(' '.join(map(str, ids)), flush=True)
sys.stdin.read()                        # hold the claim until the test closes stdin
'''
WAIT_S = 120.0


class Claimant:
    """A child process that claims a block of POOL in ``folder`` and holds it."""

    def __init__(self, folder):
        self.process = subprocess.Popen(
            [sys.executable, '-c', CLAIM, str(REPO / 'test'), str(folder)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def ids(self) -> set[int]:
        """Return the ids it claimed (it prints them once it holds them)."""
        line = self.process.stdout.readline()
        assert line, self.process.stderr.read()
        return set(map(int, line.split()))

    def end(self) -> tuple[int, str]:
        """Let it go (it ends, and with it its claim): its exit status and stderr."""
        _, stderr = self.process.communicate(timeout=WAIT_S)
        return self.process.returncode, stderr


def test_two_processes_claim_disjoint_blocks_until_they_end(tmp_path):
    first, second = Claimant(tmp_path), Claimant(tmp_path)
    try:
        a, b = first.ids(), second.ids()
        assert len(a) == len(b) == 4 and not a & b and a | b == set(POOL)
        third = Claimant(tmp_path)              # the pool is used up: a clear refusal
        status, stderr = third.end()
        assert status != 0 and 'is claimed by another process' in stderr
        assert first.end()[0] == 0              # its claim ends with it ...
        again = Claimant(tmp_path)
        assert again.ids() == a                 # ... and the block is free again
        assert again.end()[0] == 0
    finally:
        for claimant in (first, second):
            if claimant.process.poll() is None:
                claimant.process.kill()
                claimant.process.communicate()


def test_two_claims_in_one_process_are_disjoint_too(tmp_path):
    (a, lock_a), (b, lock_b) = (claim_domain_block(4, POOL, tmp_path) for _ in range(2))
    try:
        assert not set(a) & set(b)
        with pytest.raises(RuntimeError, match='is claimed by another process'):
            claim_domain_block(4, POOL, tmp_path)
    finally:
        lock_a.close()
        lock_b.close()


def test_this_session_has_one_domain_of_its_block_for_each_purpose():
    ids = [session_domain_id(purpose) for purpose in DOMAIN_PURPOSES]
    assert len(set(ids)) == len(ids) and set(ids) <= set(DOMAIN_IDS)
    assert max(ids) - min(ids) == len(ids) - 1                  # one block
    assert [session_domain_id(p) for p in DOMAIN_PURPOSES] == ids    # claimed once
