"""Higher-order SVD of a force tensor (thesis ch. 4; Zhao et al., AIAA J. 57(6) 2019).

The training data form a tensor ``A`` of shape (p1 conditions, p2 steps, p3 components).
Each component is divided by a scale (its root-mean-square over the whole tensor) so that a
small component (Fx) is not lost next to a large one (Fz). Optionally the mean trajectory
over conditions is subtracted first (``center=True``, our default; see :func:`hosvd`).

For each mode k the mode-k unfolding is decomposed by an SVD; the leading singular vectors
whose cumulative explained variance (sum of squared singular values) reaches ``energy`` are
kept (or a fixed rank). The core is ``S = A x1 U1^T x2 U2^T x3 U3^T`` and the tensor basis
``B = S x2 U2 x3 U3`` has shape (r1, p2, p3): trajectory i is ``U1[i] @ B`` (a coefficient
row vector of length D = r1 times the basis), plus the mean when centred.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, finite_array, in_range


def unfold(A: np.ndarray, mode: int) -> np.ndarray:
    """Mode-``mode`` unfolding: (A.shape[mode], prod of the other sizes)."""
    return np.moveaxis(A, mode, 0).reshape(A.shape[mode], -1)


def mode_product(A: np.ndarray, M: np.ndarray, mode: int) -> np.ndarray:
    """``A x_mode M``: contracts axis ``mode`` of A (size n) with M of shape (m, n)."""
    return np.moveaxis(np.tensordot(M, A, axes=(1, mode)), 0, mode)


def explained_variance(s: np.ndarray) -> np.ndarray:
    """Cumulative explained variance (fraction) of singular values ``s``."""
    e = np.asarray(s, float) ** 2
    tot = e.sum()
    return np.cumsum(e) / tot if tot > 0 else np.ones_like(e)


def rank_for(cumvar: np.ndarray, energy: float) -> int:
    """Smallest rank whose cumulative explained variance reaches ``energy``."""
    return int(min(np.searchsorted(cumvar, energy - 1e-12) + 1, len(cumvar)))


@dataclass(frozen=True, eq=False)
class HOSVD:
    """A truncated HOSVD. factors: [U1 (p1, r1), U2 (p2, r2), U3 (p3, r3)]; core (r1, r2, r3);
    singular: per-mode singular values (all of them); cumvar: per-mode cumulative explained
    variance; mean: (p2, p3) mean trajectory removed before the SVD (zeros if not centred)."""

    factors: list
    core: np.ndarray
    singular: list
    cumvar: list
    mean: np.ndarray

    @property
    def ranks(self) -> tuple[int, int, int]:
        return tuple(U.shape[1] for U in self.factors)

    @property
    def basis(self) -> np.ndarray:
        """Tensor basis S x2 U2 x3 U3, shape (r1, p2, p3)."""
        return mode_product(mode_product(self.core, self.factors[1], 1), self.factors[2], 2)

    @property
    def coefficients(self) -> np.ndarray:
        """Coefficients of the training cases, (p1, r1) = U1."""
        return self.factors[0]

    def reconstruct(self, coefficients: np.ndarray | None = None) -> np.ndarray:
        """Trajectories (n, p2, p3) for coefficient rows (n, r1) (default: the training cases)."""
        c = self.coefficients if coefficients is None else np.atleast_2d(coefficients)
        return np.tensordot(c, self.basis, axes=(1, 0)) + self.mean


def hosvd(A, energy: float | tuple[float, float, float] = 0.95, ranks: tuple[int | None, int | None, int | None] | None = None,
          center: bool = True) -> HOSVD:
    """Truncated higher-order SVD of a 3-way tensor ``A`` (p1, p2, p3).

    ``energy``: cumulative explained variance to keep in each mode (0 < energy <= 1), or one
    value per mode;
    ``ranks``: fixed ranks per mode (None entries use ``energy``). ``center``: subtract the mean
    trajectory over mode 1 first. Why centred by default: uncentred, the mode-1 spectrum is
    dominated by the mean force curve (all conditions look alike at first order), so the 95 %
    rule keeps one or two condition modes and discards how the condition changes the forces;
    ``center=False`` is the thesis's plain form.
    """
    A = finite_array("tensor", A, ndim=3)
    energies = tuple(energy) if np.ndim(energy) else (energy,) * 3
    if len(energies) != 3:
        raise InputError("energy", f"need 1 or 3 values, got {len(energies)}")
    energies = tuple(in_range("energy", e, 1e-9, 1.0) for e in energies)
    if A.shape[0] < 2:
        raise InputError("tensor", f"need at least 2 conditions, got {A.shape[0]}")
    mean = A.mean(axis=0) if center else np.zeros(A.shape[1:])
    X = A - mean
    if not np.any(X):
        raise InputError("tensor", "all training cases are identical: nothing to learn from the condition")
    ranks = tuple(ranks) if ranks is not None else (None, None, None)
    if len(ranks) != 3:
        raise InputError("ranks", f"need 3 entries (one per mode), got {len(ranks)}")
    factors, singular, cumvar = [], [], []
    for k in range(3):
        U, s, _ = np.linalg.svd(unfold(X, k), full_matrices=False)
        cv = explained_variance(s)
        maxr = len(s)
        if k == 0 and center:
            maxr = min(maxr, A.shape[0] - 1)  # centring removes one dimension
        # Drop numerically-zero singular values (rank-deficient unfoldings).
        maxr = max(1, min(maxr, int(np.sum(s > s[0] * 1e-12))))
        r = ranks[k]
        if r is None:
            r = min(rank_for(cv, energies[k]), maxr)
        elif not 1 <= int(r) <= len(s):
            raise InputError("ranks", f"mode {k + 1} rank must be in [1, {len(s)}], got {r}")
        factors.append(U[:, : int(r)])
        singular.append(s)
        cumvar.append(cv)
    core = X
    for k in range(3):
        core = mode_product(core, factors[k].T, k)
    return HOSVD(factors, core, singular, cumvar, mean)
