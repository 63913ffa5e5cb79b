"""A well-conditioned state-space realisation of the plant for the exact flows (high-order and stiff plants).

python-control realises a transfer function in companion form. For a high-order plant (a Padé chain of order 8
around a servo: order 12) its states span 20 orders of magnitude on a slow orbit, the output row adds terms 1e11
times larger than the output, and the relative tolerances of the switch tests (rounding of r . A^k z bounded by
|r| |A|^k |z|) lose their meaning: the flow then reports a sliding release that does not happen. The exact flow
of :class:`~dfloop.hybrid.loop.HybridLoop` (piecewise-affine elements) therefore runs in the realisation
:func:`conditioned` returns:

1. real Schur form (orthogonal), then block-diagonalised by Sylvester equations between clusters of eigenvalues
   (eigenvalues within ``CLUSTER`` relative distance stay in one block, so every Sylvester solve is well
   conditioned): the modes decouple and A's entries become O(|eigenvalue|);
2. balanced (square-root method) on the plant shifted by alpha I, alpha beyond every pole's real part, so that
   integrators and unstable poles have Gramians too; a similarity transform commutes with the shift, so the
   result realises the same plant. Balanced, the states are commensurate with the output (controllability and
   observability Gramians equal and diagonal) and the output row cancels little at any frequency.

Plants of order up to ``LOW_ORDER`` (6) keep python-control's realisation: there the companion form is
accurate, and it keeps the structural zeros of the Markov parameters (C B = 0 ... for a relative degree > 1)
exact, which a dense realisation holds only to rounding (``python benchmarks/bench_exact.py --high-order``: the
relative error of C(jw - A)^-1 B of an order-6 lag chain at 100 rad/s, where |G| = 1e-12, is 2e-5 balanced and
2e-16 in companion form).

When the balancing is ill-determined (a Hankel singular value at rounding level: a non-minimal plant, or a
mode too fast to matter, such as a lag at 1e4 times the other poles) the block-diagonal form of step 1 is used,
each block's input and output rows scaled to one size; when step 1 fails (a Schur reordering that splits a
cluster) the realisation is kept as given and the returned ``basis`` is the identity.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import eigh, schur, solve_continuous_lyapunov, solve_sylvester, svd

__all__ = ["conditioned", "CLUSTER", "LOW_ORDER"]

CLUSTER = 1e-2            # eigenvalues within this relative distance share a diagonal block
LOW_ORDER = 6             # plants up to this order keep their realisation (see the module)
_MINIMAL = 1e-13          # smallest / largest Hankel singular value below this: not minimal, not balanced


def conditioned(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """(A', B', C', V) with A' = V^-1 A V, B' = V^-1 B, C' = C V: the plant in a block-diagonal balanced
    realisation (states s = V s'), or (A, B, C, I) unchanged for a plant of order at most ``LOW_ORDER`` or when
    that is ill-determined (see the module)."""
    n = A.shape[0]
    eye = np.eye(n)
    if n <= LOW_ORDER:
        return A, B, C, eye
    try:
        Ad, V, bounds = _block_diagonal(A)
        Bd, Cd = np.linalg.solve(V, B), C @ V
        for a, b in bounds:      # each block's input and output rows of one size: the Gramians stay well scaled
            nb, nc = np.linalg.norm(Bd[a:b]), np.linalg.norm(Cd[a:b])
            if nb > 0.0 and nc > 0.0:
                d = np.sqrt(nb / nc)
                Bd[a:b] /= d
                Cd[a:b] *= d
                V[:, a:b] *= d
    except (np.linalg.LinAlgError, ValueError, _Unbalanced):
        return A, B, C, eye
    try:
        Ab, Bb, Cb, W = _balanced(Ad, Bd, Cd)
    except (np.linalg.LinAlgError, ValueError, _Unbalanced):
        Ab, Bb, Cb, W = Ad, Bd, Cd, eye      # a Hankel singular value at rounding level: the modal form
    basis = V @ W
    if not all(np.all(np.isfinite(m)) for m in (Ab, Bb, Cb, basis)):
        return A, B, C, eye
    return Ab, Bb, Cb, basis


class _Unbalanced(RuntimeError):
    pass


def _clusters(lam: np.ndarray) -> list[np.ndarray]:
    """Eigenvalues grouped: conjugates together, and any two within ``CLUSTER`` of their size (transitively)."""
    n = lam.size
    floor = 1e-8 * max(float(np.abs(lam).max()), 1e-300)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            near = abs(lam[i] - lam[j]) <= CLUSTER * max(abs(lam[i]), abs(lam[j]), floor)
            pair = abs(lam[i] - np.conj(lam[j])) <= CLUSTER * max(abs(lam[i]), floor)
            if near or pair:
                parent[find(i)] = find(j)
    roots = [find(i) for i in range(n)]
    return [lam[[k for k in range(n) if roots[k] == r]] for r in dict.fromkeys(roots)]


def _block_diagonal(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
    """(D, V, bounds): D = V^-1 A V block diagonal (one block per eigenvalue cluster, each block quasi-triangular with its
    2x2 blocks scaled to rotation form; ``bounds`` the (start, stop) of each block), by an ordered real Schur form and one Sylvester equation per cluster."""
    n = A.shape[0]
    T, V = schur(A, output="real")
    groups = _clusters(np.linalg.eigvals(A))
    start = 0
    bounds = []
    for g, group in enumerate(groups[:-1]):
        rest = np.concatenate(groups[g + 1:])

        def mine(re, im, group=group, rest=rest):
            z = re + 1j * im
            return bool(np.min(np.abs(group - z)) < np.min(np.abs(rest - z)))

        sub, Z, sdim = schur(T[start:, start:], output="real", sort=mine)
        if sdim != group.size:
            raise _Unbalanced("the Schur reordering split a cluster")
        V[:, start:] = V[:, start:] @ Z
        T[start:, start:] = sub
        k = group.size
        X = solve_sylvester(sub[:k, :k], -sub[k:, k:], -sub[:k, k:])   # T11 X - X T22 = -T12
        V[:, start + k:] += V[:, start:start + k] @ X
        T[start:start + k, start + k:] = 0.0
        bounds.append((start, start + k))
        start += k
    bounds.append((start, n))
    for a, b in bounds:          # 2x2 blocks [[p, q], [r, p]] to rotation form |q| = |r|
        if b - a == 2 and T[a, a + 1] != 0.0 and T[a + 1, a] != 0.0:
            d = np.sqrt(abs(T[a + 1, a] / T[a, a + 1]))
            T[a, a + 1] *= d
            T[a + 1, a] /= d
            V[:, a + 1] *= d
    return T, V, bounds


def _balanced(A, B, C):
    """Square-root balancing of (A - alpha I, B, C), alpha beyond every pole: (A', B', C', W), s = W s'."""
    n = A.shape[0]
    lam = np.linalg.eigvals(A)
    size = np.abs(lam)
    nonzero = size[size > 1e-9 * max(float(size.max()), 1e-300)]
    alpha = max(float(lam.real.max()), 0.0) + 0.5 * (float(nonzero.min()) if nonzero.size else 1.0)
    shifted = A - alpha * np.eye(n)
    Wc = solve_continuous_lyapunov(shifted, -np.outer(B, B))
    Wo = solve_continuous_lyapunov(shifted.T, -np.outer(C, C))
    Lc, Lo = _root(Wc), _root(Wo)
    U, S, Vt = svd(Lo.T @ Lc)
    if not (S.size and S[-1] > _MINIMAL * S[0]):
        raise _Unbalanced("not minimal")
    W = Lc @ Vt.T / np.sqrt(S)
    Wi = (U / np.sqrt(S)).T @ Lo.T
    return Wi @ A @ W, Wi @ B, C @ W, W


def _root(W: np.ndarray) -> np.ndarray:
    """L with L L^T = W for a symmetric positive semidefinite W (negative rounding eigenvalues cut to 0)."""
    e, U = eigh(0.5 * (W + W.T))
    return U * np.sqrt(np.clip(e, 0.0, None))
