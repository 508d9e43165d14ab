"""
The one way the time loop's kernels are compiled: numba, nopython, cached on disk.

Every kernel of the loop is decorated with :func:`kernel` (helpers compiled into the
kernels that call them with :func:`inline`). Compiled code is kept on disk, so only the first
start after a change of the kernels' source pays the compilation (several seconds); later
starts load it in milliseconds.

Where. numba checks a cached kernel against its own source file only, not against the
kernels it calls from other modules. The cache therefore lives in a folder named after a
hash of the source of every kernel-defining module of the package and of the package modules
they import (``kernels-<hash>``, :func:`kernel_modules`): editing any of them starts a fresh
cache. Inside it a kernel is found by its module's name, its line and its
source file's content, not by the file's path (numba's own locators add a folder per source
path): a second checkout or a new virtual environment with the same kernels loads them instead
of compiling them again. The folder is made under the first writable of: ``NUMBA_CACHE_DIR``,
the user's cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``)/drill_twin, ``__pycache__``
beside this file, the system's temporary folder; with none writable the kernels are compiled
at every start (with a warning). Of the folders of earlier sources, the KEPT_CACHES most
recently used are kept (about 7 MB each), older ones removed.

Kernels run on one thread (the batch is the vector axis) and use numpy's error model:
a division by zero gives inf or nan as in numpy, never an exception, so a diverging member
is caught by the integrator's finiteness checks exactly as before. No fastmath: results keep
numpy's rounding rules and nan/inf propagate.

Vector code. A loop over the members that reads and writes many rows of work arrays (the
finite strain's stress at a Gauss point: 16 rows read, 8 written) is vectorised by LLVM only
behind run-time checks that the rows do not overlap; the cost model's default limit (128
checks) turned that loop scalar. The limit is raised to VECTOR_MEMORY_CHECKS for the process
(an LLVM option: it changes which loops get vector code, never a result: the loops without
fastmath are element-wise, reductions are not reordered). Measured: the 64-member stress loop
1170 -> 271 ns per Gauss point, bit for bit the same.
"""
from __future__ import annotations

import ast
import hashlib
import os
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import llvmlite.binding
import numba
from numba.core import caching

VECTOR_MEMORY_CHECKS = 256
"""LLVM's limit on the run-time alias checks of a vectorised loop (module docstring)."""
llvmlite.binding.set_option(
    'drill_twin', f'-vectorize-memory-check-threshold={VECTOR_MEMORY_CHECKS}')

OPTIONS = dict(nogil=True, error_model='numpy')
"""Compilation options shared by every kernel."""
VECTOR_BATCH = 4
"""From this batch size on, kernels loop over the members innermost (the vector axis); below
it, member by member (a loop over one member costs more in set-up than it computes)."""
_MARKERS = (b'@kernel', b'@inline')
KEPT_CACHES = 6
"""Folders of earlier kernel sources kept beside the current one (module docstring)."""


def kernel_modules() -> list[Path]:
    """
    List the modules whose source the compiled kernels depend on, in a fixed order.

    This module, every module of the package that defines kernels (``@kernel``, ``@inline``),
    and every package module those import, transitively: a plain function compiled into a
    kernel (the Newmark scheme's predictor, a constant) changes the kernels as much as the
    kernel's own source does.
    """
    package = Path(__file__).resolve().parents[1]
    by_name = {'.'.join((package.name, *path.relative_to(package).with_suffix('').parts)): path
               for path in package.rglob('*.py')}
    by_name = {name.removesuffix('.__init__'): path for name, path in by_name.items()}
    wanted = {Path(__file__).resolve()} | {
        path.resolve() for path in by_name.values()
        if any(marker in path.read_bytes() for marker in _MARKERS)}
    queue = list(wanted)
    while queue:
        for name in _imported_modules(queue.pop()):
            path = by_name.get(name)
            if path is not None and path.resolve() not in wanted:
                wanted.add(path.resolve())
                queue.append(path.resolve())
    return sorted(wanted)


def _imported_modules(path: Path) -> set[str]:
    """Dotted names a module imports (``import a.b``, ``from a.b import c``: a.b and a.b.c)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_bytes(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f'{node.module}.{alias.name}' for alias in node.names)
    return names


def _source_hash() -> str:
    """Hash of :func:`kernel_modules`' names (relative to the package) and contents."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for path in kernel_modules():
        digest.update(path.relative_to(package).as_posix().encode() + b'\0' + path.read_bytes())
    return digest.hexdigest()[:16]


def _writable(directory: Path) -> bool:
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
        return True
    except OSError:
        return False


def cache_directory() -> Path | None:
    """Return the kernels' cache folder (module docstring), None when nothing is writable."""
    user_cache = Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache')
    bases = [Path(os.environ['NUMBA_CACHE_DIR'])] if os.environ.get('NUMBA_CACHE_DIR') else []
    bases += [user_cache / 'drill_twin', Path(__file__).parent / '__pycache__',
              Path(tempfile.gettempdir()) / f'drill_twin-{os.getuid()}']
    name = f'kernels-{_source_hash()}'
    for base in bases:
        if _writable(base / name):
            try:
                os.utime(base / name)                   # in use: the last to be pruned
            except OSError:
                pass
            _prune(base, keep=base / name)
            return base / name
    return None


def _prune(base: Path, keep: Path) -> None:
    """Remove the oldest ``kernels-*`` folders of ``base`` beyond KEPT_CACHES (not ``keep``)."""
    try:
        folders = sorted((path for path in base.glob('kernels-*')
                          if path.is_dir() and path != keep),
                         key=lambda path: path.stat().st_mtime, reverse=True)
    except OSError:
        return
    day = 86400.0
    for path in folders[KEPT_CACHES:]:
        try:
            if time.time() - path.stat().st_mtime > day:   # not one another process just made
                shutil.rmtree(path, ignore_errors=True)
        except OSError:
            pass


class _KernelLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
    """
    numba's cache locator for this package's kernels: the folder of cache_directory().

    A kernel's files are named by its module, function and line (numba's names) and checked
    against a hash of its source file's content (numba's stamp), with no folder per source
    path: the same kernels in another checkout find them.
    """

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno

    def get_cache_path(self):
        return str(_CACHE_DIRECTORY)


class _KernelCacheImpl(caching.CompileResultCacheImpl):
    _locator_classes = [_KernelLocator]


class _KernelCache(caching.FunctionCache):
    _impl_class = _KernelCacheImpl


_CACHE_DIRECTORY = cache_directory()


def kernel(function):
    """Compile ``function`` with numba.njit (nopython mode) and the on-disk cache."""
    dispatcher = numba.njit(cache=False, **OPTIONS)(function)
    if _CACHE_DIRECTORY is None:
        warnings.warn(f'drill_twin: no writable folder for the compiled kernels; '
                      f'{function.__name__} is compiled at every start (set NUMBA_CACHE_DIR)',
                      stacklevel=2)
    else:
        try:
            dispatcher._cache = _KernelCache(function)  # what njit(cache=True) sets, ours
        except RuntimeError:                            # no source file to stamp (a zip...)
            dispatcher.enable_caching()                 # numba's own locators
    return dispatcher


def inline(function):
    """Compile a helper of kernels into each kernel that calls it (not cached on its own)."""
    return numba.njit(inline='always', **OPTIONS)(function)
