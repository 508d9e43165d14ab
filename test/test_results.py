"""scripts/make_results.py and docs/results: regenerated results carry a MANIFEST that is right."""
from __future__ import annotations

import datetime
import hashlib
import json
from pathlib import Path
import re
import subprocess
import sys

import pytest
import yaml
from conftest import REPO

from drill_twin.config import yaml_io

SCRIPT = REPO / 'scripts' / 'make_results.py'
RESULTS = REPO / 'docs' / 'results'
MANIFEST_KEYS = {'command', 'commit', 'source_modified', 'config', 'config_sha256', 'seed',
                 'date', 'files'}
MAX_RESULTS_BYTES = 8 * 1024 * 1024
PAPER_TORSIONAL_HZ = (0.2144, 3.2138)
"""Table 1's first two torsional modes (ranks 13 and 162 of the reduced basis)."""


def sha256_of_canonical_json(mapping: dict) -> str:
    """Return the MANIFEST's configuration hash, written out here from its definition."""
    text = json.dumps(mapping, sort_keys=True, separators=(',', ':'), ensure_ascii=False)
    return hashlib.sha256(text.encode('utf-8')).hexdigest()


def file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def git(*args: str) -> str:
    return subprocess.run(['git', *args], cwd=REPO, check=True, capture_output=True,
                          text=True).stdout.strip()


@pytest.fixture(scope='module')
def regenerated(tmp_path_factory):
    """Table 1 and a 1 s mean-model run written by the script into a temporary root."""
    root = tmp_path_factory.mktemp('results')
    before = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    completed = subprocess.run(
        [sys.executable, str(SCRIPT), 'table1', 'mean_model', '--root', str(root),
         '--mean-model-duration', '1'], cwd=REPO, capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr[-2000:]
    after = datetime.datetime.now(datetime.timezone.utc)
    return root, before, after


@pytest.mark.parametrize('name', ['table1', 'mean_model'])
def test_manifest_names_the_commit_the_configuration_and_the_files(regenerated, name):
    root, before, after = regenerated
    directory = root / name
    manifest = json.loads((directory / 'MANIFEST.json').read_text())
    assert set(manifest) == MANIFEST_KEYS
    assert manifest['commit'] == git('rev-parse', 'HEAD')
    assert isinstance(manifest['source_modified'], bool)
    assert manifest['seed'] is None                      # both runs draw nothing at random
    assert manifest['config'] == 'config/ritto2009.yaml'
    shipped = yaml_io.safe_load((REPO / 'config' / 'ritto2009.yaml').read_text())
    assert manifest['config_sha256'] == sha256_of_canonical_json(shipped)
    beside = yaml.safe_load((directory / 'config.yaml').read_text())
    assert sha256_of_canonical_json(beside) == manifest['config_sha256']
    date = datetime.datetime.fromisoformat(manifest['date'])
    assert date.utcoffset() == datetime.timedelta(0)
    assert before <= date <= after
    assert 'config.yaml' in manifest['files']
    for file, digest in manifest['files'].items():
        assert file_sha256(directory / file) == digest, file
    for line in manifest['command']:
        assert str(directory) in line


def test_table1_lists_the_reduced_basis_with_the_papers_column(regenerated):
    root, _, _ = regenerated
    directory = root / 'table1'
    manifest = json.loads((directory / 'MANIFEST.json').read_text())
    assert manifest['command'][0].startswith('drill-twin modes')
    modes = json.loads((directory / 'modes.json').read_text())['modes']
    rows = [line.split() for line in (directory / 'table1.txt').read_text().splitlines()
            if re.match(r'\s+\d+\s', line)]
    assert [int(row[0]) for row in rows] == list(range(1, len(modes) + 1))
    assert [float(row[1]) for row in rows] == [round(m['frequency_hz'], 4) for m in modes]
    torsional = [m['frequency_hz'] for m in modes if m['type'] == 'torsional']
    assert torsional[0] == pytest.approx(PAPER_TORSIONAL_HZ[0], rel=1e-3)
    assert torsional[-1] == pytest.approx(PAPER_TORSIONAL_HZ[1], rel=1e-3)


def test_mean_model_writes_its_figure_and_the_summary_over_the_run(regenerated):
    root, _, _ = regenerated
    directory = root / 'mean_model'
    manifest = json.loads((directory / 'MANIFEST.json').read_text())
    assert '--duration 1 ' in manifest['command'][0]
    assert (directory / 'mean_model.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    summary = json.loads((directory / 'summary.json').read_text())
    assert summary['window_s'] == pytest.approx(1.0, abs=0.01)
    assert summary['bit_speed_rad_per_s']['min'] <= summary['bit_speed_rad_per_s']['max']


def test_an_unknown_name_is_refused_in_one_line(tmp_path):
    completed = subprocess.run([sys.executable, str(SCRIPT), 'tabel1', '--root', str(tmp_path)],
                               cwd=REPO, capture_output=True, text=True)
    assert completed.returncode != 0
    assert completed.stderr.strip().splitlines() == [
        "make_results: no result or group 'tabel1' (--list names them)"]
    assert not any(tmp_path.iterdir())


def tracked_results() -> list[Path]:
    return [REPO / name for name in git('ls-files', '--', 'docs/results').splitlines()]


def test_docs_results_keeps_figures_and_tables_within_8_mb():
    files = [path for path in tracked_results() if path.exists()]
    assert sum(path.stat().st_size for path in files) <= MAX_RESULTS_BYTES
    kinds = {path.suffix for path in files}
    assert kinds <= {'.png', '.csv', '.json', '.txt', '.yaml', '.md'}, kinds


def test_every_results_directory_matches_its_manifest():
    tracked = {path for path in tracked_results() if path.exists()}
    directories = {path.parent for path in tracked if path.parent != RESULTS}
    assert directories
    for directory in sorted(directories):
        manifest = json.loads((directory / 'MANIFEST.json').read_text())
        assert MANIFEST_KEYS <= set(manifest), directory
        assert git('cat-file', '-t', manifest['commit']) == 'commit'
        beside = yaml.safe_load((directory / 'config.yaml').read_text())
        assert sha256_of_canonical_json(beside) == manifest['config_sha256'], directory
        kept = {path.name for path in directory.iterdir()
                if path in tracked and path.name != 'MANIFEST.json'}
        assert kept == set(manifest['files']), directory
        for file, digest in manifest['files'].items():
            assert file_sha256(directory / file) == digest, (directory, file)


def test_the_index_lists_every_results_directory():
    index = (RESULTS / 'README.md').read_text()
    for manifest in RESULTS.rglob('MANIFEST.json'):
        name = manifest.parent.relative_to(RESULTS).as_posix()
        assert f'`{name}/`' in index, name


def test_every_figure_or_table_a_document_links_exists():
    documents = [REPO / name for name in git('ls-files', '--', '*.md').splitlines()]
    for document in documents:
        for target in re.findall(r'\]\(([^)\s#]+)', document.read_text()):
            path = (document.parent / target).resolve()
            if RESULTS in path.parents or REPO / 'docs' / 'figures' in path.parents:
                assert path.exists(), (document.relative_to(REPO).as_posix(), target)
