"""Sparse assembly of element arrays from precomputed DOF maps."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def assemble_matrix(element_matrices: np.ndarray, element_dofs: np.ndarray,
                    n_dofs: int) -> sp.csr_matrix:
    """Global sparse matrix from (n_el, 12, 12) blocks; duplicates are summed."""
    n = element_dofs.shape[1]
    rows = np.repeat(element_dofs, n, axis=1).ravel()
    cols = np.tile(element_dofs, (1, n)).ravel()
    matrix = sp.coo_matrix((element_matrices.ravel(), (rows, cols)), shape=(n_dofs, n_dofs))
    return matrix.tocsr()


def assemble_vector(element_vectors: np.ndarray, element_dofs: np.ndarray,
                    n_dofs: int) -> np.ndarray:
    """Global vector from (..., n_el, 12) element vectors; leading axes are kept."""
    lead = element_vectors.shape[:-2]
    out = np.zeros(lead + (n_dofs,))
    flat = element_vectors.reshape(lead + (-1,))
    np.add.at(out, (..., element_dofs.ravel()), flat)
    return out


def point_matrix(rows: np.ndarray, dofs: np.ndarray, coefficient: float,
                 n_dofs: int) -> sp.csr_matrix:
    """
    Return coefficient * r^T r for interpolation rows r (n_rows, 12) on the element DOFs.

    The element DOFs are ``dofs``.
    """
    block = coefficient * np.einsum('ri,rj->ij', rows, rows)
    return assemble_matrix(block[None], dofs[None], n_dofs)
