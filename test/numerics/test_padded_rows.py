"""The padded-row layout of the force kernels' operators (drill_twin.numerics.padded_rows)."""
import numpy as np
import scipy.sparse as sp

from drill_twin.numerics.padded_rows import padded_rows, padded_rows_of


def _dense(columns, values, width_of):
    rows = columns.shape[0]
    dense = np.zeros((rows, width_of))
    for r in range(rows):
        for c, v in zip(columns[r], values[r]):
            dense[r, c] += v                                  # padding adds exact zeros
    return dense


def test_padded_rows_hold_the_matrix_and_each_rows_length():
    rng = np.random.default_rng(7)
    dense = rng.normal(size=(9, 6)) * (rng.random((9, 6)) < 0.4)
    dense[3] = 0.0                                            # an empty row
    dense[5] = rng.normal(size=6)                             # the longest: all six
    columns, values, lengths = padded_rows_of(dense)
    assert columns.shape == values.shape == (9, 6)
    np.testing.assert_array_equal(lengths, np.count_nonzero(dense, axis=1))
    np.testing.assert_array_equal(_dense(columns, values, 6), dense)
    for r in range(9):                                        # non-zeros first, in order
        np.testing.assert_array_equal(columns[r, :lengths[r]], np.flatnonzero(dense[r]))
        assert np.all(values[r, lengths[r]:] == 0.0)


def test_a_padded_row_sums_bit_for_bit_like_its_compressed_row():
    rng = np.random.default_rng(8)
    matrix = sp.random(40, 30, density=0.15, random_state=9, format='csr')
    matrix.sort_indices()
    x = rng.normal(size=30)
    columns, values, _ = padded_rows(matrix.indptr, matrix.indices, matrix.data)
    for r in range(40):
        compressed = 0.0
        for j in range(matrix.indptr[r], matrix.indptr[r + 1]):
            compressed += matrix.data[j] * x[matrix.indices[j]]
        padded = 0.0
        for c, v in zip(columns[r], values[r]):
            padded += v * x[c]
        assert padded == compressed


def test_several_index_arrays_are_padded_alike():
    pointer = np.array([0, 2, 2, 3])
    rows, cols, vals = np.array([4, 5, 6]), np.array([1, 2, 3]), np.array([1.0, 2.0, 3.0])
    (padded_rows_, padded_cols), values, lengths = padded_rows(pointer, (rows, cols), vals)
    np.testing.assert_array_equal(padded_rows_, [[4, 5], [0, 0], [6, 6]])
    np.testing.assert_array_equal(padded_cols, [[1, 2], [0, 0], [3, 3]])
    np.testing.assert_array_equal(values, [[1.0, 2.0], [0.0, 0.0], [3.0, 0.0]])
    np.testing.assert_array_equal(lengths, [2, 0, 1])
