"""A readable RATTLE on the full 12-coordinate director system, in plain numpy.

This is the check of the fast kernel, not a production path (about 1e3 times slower). It
follows Andersen (1983) literally, with the six Lagrange multipliers of the constraints
g(D) = D^T D - I (upper triangle) and the director mass matrix M = Jbar (x) 1 (plus m 1 for
a free centre of mass). The mass matrix is never inverted: each half of the step is a
saddle-point system solved for the positions (or velocities) and the multipliers together,
so flat bodies (a zero convected moment, M singular) work.

One step of size h, with F the (constant) director force of gravity on a pivoted body:

    SHAKE:   (D1 - D0 - h V0) Jbar + D0 mu - h^2/2 F = 0,   D1^T D1 = I
             (mu = h^2/2 Lambda; Newton on the 15 unknowns D1, mu)
             V_half = (D1 - D0)/h
    RATTLE:  (V1 - V_half) Jbar + D1 nu - h/2 F = 0,        D1^T V1 + V1^T D1 = 0
             (nu = h/2 N; a linear 15 x 15 system)

and for a free centre of mass the exact free flight x1 = x0 + h v0 + h^2/2 g, v1 = v0 + h g
(RATTLE on a linear potential). McLachlan & Zanna (2005) show that this map equals the
discrete Moser-Veselov step computed by :mod:`director_model._kernels`; the test suite checks
the two implementations against each other.

Vectorisation convention: a 3x3 matrix X is flattened column by column (x = X.T.ravel(),
director d_j at entries 3j..3j+2), so vec(A X B) = (B^T kron A) vec(X).
"""

from __future__ import annotations

import numpy as np

# the six constraint / multiplier index pairs (k, l), k <= l
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))

# E maps the 6 parameters of a symmetric 3x3 matrix to its column-major 9-vector
_E = np.zeros((9, 6))
for _q, (_k, _l) in enumerate(_PAIRS):
    _E[3 * _l + _k, _q] = 1.0
    _E[3 * _k + _l, _q] = 1.0


def _vec(X):
    return X.T.ravel()


def _unvec(x):
    return x.reshape(3, 3).T


def _constraints(D):
    C = D.T @ D - np.eye(3)
    return np.array([C[k, l] for k, l in _PAIRS])


def _constraint_jacobian(D):
    """Rows: d g_q / d vec(D) for g_q = d_k . d_l - delta_kl."""
    G = np.zeros((6, 9))
    for q, (k, l) in enumerate(_PAIRS):
        G[q, 3 * k : 3 * k + 3] += D[:, l]
        G[q, 3 * l : 3 * l + 3] += D[:, k]
    return G


class DirectorRattle:
    """Plain-numpy RATTLE for one body. Build with the same physical arguments as
    :func:`director_model.simulate` (they are assumed valid), then call :meth:`step`."""

    def __init__(self, mass, inertia, *, gravity=(0.0, 0.0, 0.0), pivot=None):
        I = np.asarray(inertia, dtype=float)
        self.m = float(mass)
        J = 0.5 * (I.sum() - 2.0 * I)  # convected moments J_i = (I_j + I_k - I_i)/2
        self.c = None if pivot is None else np.asarray(pivot, dtype=float)
        self.Jbar = np.diag(J) if self.c is None else np.diag(J) + self.m * np.outer(self.c, self.c)
        self.g = np.asarray(gravity, dtype=float)
        # director force of gravity: V = -m g . x_G = m g . (D c)  =>  F = -dV/dD = -m g c^T
        self.F = np.zeros((3, 3)) if self.c is None else -self.m * np.outer(self.g, self.c)
        self.A = np.kron(self.Jbar.T, np.eye(3))  # vec(X Jbar) = A vec(X)

    def step(self, x, v, D, V, h):
        """One RATTLE step: returns (x1, v1, D1, V1). Raises RuntimeError if SHAKE's Newton
        iteration does not converge (a readable reference has no step-size logic)."""
        # --- SHAKE: positions and multipliers together
        B = np.kron(np.eye(3), D) @ _E  # vec(D0 mu) = B mu6
        D1 = D + h * V
        mu = np.zeros(6)
        polish = False
        for _ in range(50):
            r = np.concatenate(
                [_vec((D1 - D - h * V) @ self.Jbar) + B @ mu - _vec(0.5 * h * h * self.F),
                 _constraints(D1)]
            )  # fmt: skip
            K = np.block([[self.A, B], [_constraint_jacobian(D1), np.zeros((6, 6))]])
            dz = np.linalg.solve(K, r)
            D1 = D1 - _unvec(dz[:9])
            mu = mu - dz[9:]
            if polish:
                break
            # quadratic convergence: once the correction is below 1e-10, one more Newton
            # iteration lands at round-off
            polish = np.max(np.abs(dz)) <= 1e-10
        else:
            raise RuntimeError("SHAKE Newton iteration did not converge")
        V_half = (D1 - D) / h
        # --- RATTLE velocity projection: linear saddle-point system
        B1 = np.kron(np.eye(3), D1) @ _E
        G1 = _constraint_jacobian(D1)  # g'(D1) vec(V1) = vec of D1^T V1 + V1^T D1 (pairs)
        K = np.block([[self.A, B1], [G1, np.zeros((6, 6))]])
        rhs = np.concatenate([self.A @ _vec(V_half) + _vec(0.5 * h * self.F), np.zeros(6)])
        sol = np.linalg.solve(K, rhs)
        V1 = _unvec(sol[:9])
        if self.c is None:
            x1 = x + h * v + 0.5 * h * h * self.g
            v1 = v + h * self.g
        else:
            x1 = -D1 @ self.c
            v1 = -V1 @ self.c
        return x1, v1, D1, V1

    def run(self, x, v, D, V, h, nstep):
        """nstep steps; returns arrays x, v (nstep+1, 3), D, V (nstep+1, 3, 3)."""
        out = [(np.asarray(x, float), np.asarray(v, float), np.asarray(D, float),
                np.asarray(V, float))]  # fmt: skip
        for _ in range(nstep):
            out.append(self.step(*out[-1], h))
        return tuple(np.array([o[i] for o in out]) for i in range(4))
