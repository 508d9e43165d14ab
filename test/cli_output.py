"""Checks of what the drill-twin command prints, shared by the CLI tests."""


def assert_one_line(result, *words):
    """Assert a refused input: exit status 2, one stderr line 'drill-twin: ...' with ``words``."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr[-3000:]
    assert lines[0].startswith('drill-twin: '), lines[0]
    for word in words:
        assert word in lines[0], lines[0]
