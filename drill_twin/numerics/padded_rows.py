"""
Sparse rows padded to one length: the layout of the force kernels' interpolation operators.

Row r of a sparse matrix is kept as its non-zeros in column order followed by padding (the
row's first column, value 0) up to the longest row's length R: arrays (rows, R). A kernel then
runs loops of one fixed length, about a third cheaper than the short loops of varying length
of compressed rows (measured on the finite-strain kernel: 28 -> 20 us for the paper's 224
Gauss points and one member), and the padding adds exact zeros: sums over a padded row are
those over its non-zeros, bit for bit, for finite operands. Kernels whose inner loop runs
over a batch's members stop at each row's own length instead (the padding would cost them a
seventh more work).

Column indices are unsigned (np.uintp): numba checks every signed index for a negative value
(counted from the end), an unsigned one needs no check (the finite strain's gathers and
scatters ran 12-30 % faster, the kernel 26.5 against 29.2 us for one member, measured).
"""
from __future__ import annotations

import numpy as np


def unsigned_index(index) -> np.ndarray:
    """Return ``index`` as unsigned integers (np.uintp), the kernels' index layout."""
    return np.ascontiguousarray(index, dtype=np.uintp)


def padded_rows(pointer: np.ndarray, columns, values: np.ndarray):
    """
    Return compressed rows padded to the longest: columns (rows, R) uintp, values (rows, R).

    And lengths (rows,) int64, each row's count of non-zeros: the batch kernels, whose inner
    loop runs over the members, skip the padding with them. pointer (rows + 1,), columns
    (nnz,), values (nnz,): the rows in CSR. ``columns`` may be a tuple of index arrays (each
    padded alike, returned as a tuple). R is at least 1.
    """
    several = isinstance(columns, tuple)
    columns = columns if several else (columns,)
    pointer = np.asarray(pointer)
    lengths = np.diff(pointer)
    rows, width = lengths.size, max(int(lengths.max(initial=0)), 1)
    padded = [np.zeros((rows, width), dtype=np.uintp) for _ in columns]
    padded_values = np.zeros((rows, width))
    for r in range(rows):
        start, stop = pointer[r], pointer[r + 1]
        for out, index in zip(padded, columns):
            out[r, :stop - start] = index[start:stop]
            out[r, stop - start:] = index[start] if stop > start else 0
        padded_values[r, :stop - start] = values[start:stop]
    return (tuple(padded) if several else padded[0]), padded_values, lengths.astype(np.int64)


def padded_rows_of(dense: np.ndarray):
    """Return (columns, values, lengths) (:func:`padded_rows`) of a dense (rows, k) matrix."""
    row, column = np.nonzero(dense)
    pointer = np.searchsorted(row, np.arange(dense.shape[0] + 1))
    return padded_rows(pointer, column, np.ascontiguousarray(dense[row, column], dtype=float))
