"""The compiled kernels' on-disk cache: found by content, not by path; old folders pruned."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from drill_twin.numerics import compiled

PROBE = '''
from drill_twin.numerics.compiled import kernel


@kernel
def twice(x):
    return 2.0 * x
'''

RUN = '''
import json, probe_kernel
value = probe_kernel.twice(1.5)
stats = probe_kernel.twice.stats
print(json.dumps({"value": value, "hits": sum(stats.cache_hits.values()),
                  "misses": sum(stats.cache_misses.values()),
                  "path": probe_kernel.twice._cache.cache_path}))
'''


def _run_probe(folder: Path, cache: Path) -> dict:
    environment = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(folder))
    done = subprocess.run([sys.executable, '-c', RUN], env=environment, cwd=folder,
                          capture_output=True, text=True, timeout=120, check=True)
    return json.loads(done.stdout)


def test_a_kernel_compiled_in_one_checkout_is_loaded_in_another(tmp_path):
    cache = tmp_path / 'cache'
    first, second, edited = (tmp_path / name for name in ('first', 'second', 'edited'))
    for folder, source in ((first, PROBE), (second, PROBE), (edited, PROBE + '# edited\n')):
        folder.mkdir()
        (folder / 'probe_kernel.py').write_text(source)
    compiled_once = _run_probe(first, cache)
    assert compiled_once['value'] == 3.0
    assert (compiled_once['misses'], compiled_once['hits']) == (1, 0)
    assert Path(compiled_once['path']).parent == cache          # no folder per source path
    assert Path(compiled_once['path']).name.startswith('kernels-')
    loaded = _run_probe(second, cache)                          # same content, other path
    assert (loaded['value'], loaded['misses'], loaded['hits']) == (3.0, 0, 1)
    assert loaded['path'] == compiled_once['path']
    recompiled = _run_probe(edited, cache)                      # other content: not reused
    assert (recompiled['misses'], recompiled['hits']) == (1, 0)


def test_the_oldest_cache_folders_are_pruned(tmp_path):
    now = time.time()
    folders = []
    for age_days in range(10):
        folder = tmp_path / f'kernels-{age_days:016d}'
        folder.mkdir()
        (folder / 'kernel.nbi').write_bytes(b'x')
        os.utime(folder, (now - age_days * 86400.0 - 60.0,) * 2)
        folders.append(folder)
    recent_but_many = tmp_path / 'kernels-fresh'                # beyond the count, but new
    recent_but_many.mkdir()
    os.utime(recent_but_many, (now - 7200.0,) * 2)
    current = folders[-1]                                       # the oldest, but in use
    compiled._prune(tmp_path, keep=current)
    left = sorted(path.name for path in tmp_path.iterdir())
    kept = [folder.name for folder in folders[:compiled.KEPT_CACHES - 1]]
    assert left == sorted(kept + [recent_but_many.name, current.name])


def test_the_cache_folder_follows_every_kernel_module_of_the_package():
    """
    Kernels live in several packages and compile plain functions of others (the Newmark scheme).

    Editing any of them must start a fresh cache: the hashed modules are those with a kernel
    and every package module they import, found here by a plain text search of the sources.
    """
    package = Path(compiled.__file__).resolve().parents[1]
    sources = {path.relative_to(package).as_posix(): path.read_text()
               for path in package.rglob('*.py')}
    wanted = {name for name, text in sources.items() if '@kernel' in text or '@inline' in text}
    wanted.add('numerics/compiled.py')
    grew = True
    while grew:
        grew = False
        for name in sorted(wanted):
            for other in set(sources) - wanted:
                module = 'drill_twin.' + other.removesuffix('.py').replace('/', '.')
                module = module.removesuffix('.__init__')
                parent, _, last = module.rpartition('.')
                patterns = (rf'^\s*import {re.escape(module)}\b',
                            rf'^\s*from {re.escape(module)} import\b',
                            rf'^\s*from {re.escape(parent)} import (\([^)]*|[^\n]*)\b{last}\b')
                if any(re.search(pattern, sources[name], re.M) for pattern in patterns):
                    wanted.add(other)
                    grew = True
    hashed = {path.relative_to(package).as_posix() for path in compiled.kernel_modules()}
    assert {'model/forces.py', 'integrator/newmark_kernel.py', 'analysis/kpi.py',
            'integrator/newmark_scheme.py'} <= hashed
    assert hashed == wanted
