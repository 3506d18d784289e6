"""Factorisations of the box model's matrices for repeated solves.

The box model's stiffness is about a third full (a panel's Legendre basis couples every
DOF of that panel): on the 2709-DOF Shinkansen-type model SuperLU's sparse LU fills in to
6 million entries and takes 2-3.5 s per factorisation and 25-50 ms per solve, dense
LAPACK Cholesky 0.3 s and about 10 ms. So a matrix that is that full is factorised dense
(Cholesky where it is positive definite, else LU with partial pivoting), a truly sparse
one by SuperLU.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg

#: a matrix with at least this share of non-zeros is factorised dense
DENSE_SHARE = 0.02
#: ... unless it has more rows than this (a dense copy would then cost too much memory)
DENSE_MAX_ROWS = 8000


class Factor:
    """``solve(b)`` for A x = b, b of shape (n,) or (n, k); ``kind``: "cholesky", "lu" or "splu"."""

    def __init__(self, A):
        A = sp.csc_matrix(A) if sp.issparse(A) else np.asarray(A, float)
        n = A.shape[0]
        nnz = A.nnz if sp.issparse(A) else np.count_nonzero(A)
        if n > DENSE_MAX_ROWS or nnz < DENSE_SHARE * n * n:
            self.kind, self._lu = "splu", scipy.sparse.linalg.splu(sp.csc_matrix(A))
            return
        D = A.toarray() if sp.issparse(A) else A
        try:
            self._c = scipy.linalg.cho_factor(D, lower=False, check_finite=False)
            self.kind = "cholesky"
        except np.linalg.LinAlgError:  # not positive definite (a shifted or bordered matrix)
            self._c = scipy.linalg.lu_factor(D, check_finite=False)
            self.kind = "lu"
        if not np.all(np.isfinite(self._c[0].diagonal())) or np.any(self._c[0].diagonal() == 0):
            raise RuntimeError("Factor is exactly singular")

    def solve(self, b):
        b = np.asarray(b, float)
        if self.kind == "splu":
            return self._lu.solve(b)
        if self.kind == "cholesky":
            return scipy.linalg.cho_solve(self._c, b, check_finite=False)
        return scipy.linalg.lu_solve(self._c, b, check_finite=False)

    def operator(self) -> scipy.sparse.linalg.LinearOperator:
        """The inverse as a linear operator (the ``OPinv`` of a shift-invert Lanczos solve)."""
        n = self._lu.shape[0] if self.kind == "splu" else self._c[0].shape[0]
        return scipy.sparse.linalg.LinearOperator((n, n), matvec=self.solve, matmat=self.solve, dtype=float)


def factorise(A) -> Factor:
    """A :class:`Factor` of the square matrix A (sparse or dense)."""
    return Factor(A)
