"""The singular values of the loop solver's symmetric velocity-stage matrix G M^-1 G^T
without its singular vectors, for the rank decision near a singular configuration.

The loop solver factorises that matrix as L D L^T in the row order (``_kernels``); where a
kept pivot is small but the factorisation is sound (between PIVOT_FLOOR and PIVOT_CHECK of
the largest diagonal entry) the singular values decide whether it holds the rank the
minimum-norm SVD solve would keep. For a symmetric positive semi-definite matrix they are
the absolute values of its eigenvalues, computed here by LAPACK's dsyevd with jobz = 'N'
(Householder tridiagonalisation and the eigenvalues of the tridiagonal matrix) through
numba's own wrapper, the routine of numpy.linalg.eigvalsh: about a third of the cost of
the full SVD with both sets of vectors (dgesdd, jobz = 'A') on the four-bar's 20 x 20
matrix (numpy on one core: 15 us against 42 us), whose vectors are needed only where the
SVD solves. The kernels of _kernels.py call this function (a plain call: the LAPACK call
dwarfs it); their disk cache is tied to this file.
"""

from __future__ import annotations

import math

from numba import njit, types
from numba.np.linalg import _LAPACK, ensure_lapack

ensure_lapack()
#: LAPACK's dsyevd through numba's wrapper (workspace query, then the call), as
#: numpy.linalg.eigvalsh and numba's np.linalg.eigvalsh call it
_SYEVD = _LAPACK().numba_ez_xxxevd(types.float64)
_KIND_D = ord("d")
_JOBZ_N = ord("N")
_UPLO_L = ord("L")


@njit
def _sym_sigma(A, s):
    """The singular values of the symmetric n x n A (both triangles stored; overwritten) in
    decreasing order into s (n,): the absolute values of its eigenvalues (a positive
    semi-definite matrix's smallest ones come out as rounding of either sign). Returns 0, or
    -1 if A is not finite or dsyevd failed."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            if not abs(A[i, j]) < math.inf:
                return -1
    r = _SYEVD(_KIND_D, _JOBZ_N, _UPLO_L, n, A.ctypes, n, s.ctypes)
    if r != 0:
        return -1
    for i in range(n):
        s[i] = abs(s[i])
    # insertion sort, decreasing (the eigenvalues come increasing: a few moves at most)
    for i in range(1, n):
        v = s[i]
        j = i - 1
        while j >= 0 and s[j] < v:
            s[j + 1] = s[j]
            j -= 1
        s[j + 1] = v
    return 0
