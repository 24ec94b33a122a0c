"""What the crossed random-effects models share: the participant x stimulus layout of a
cell's ratings, the block matrix it gives, and contrasts against a reference system.

Every rating belongs to one participant and one stimulus, so with Z = [Z_p, Z_s] the
indicator matrices of the two factors, any matrix ``Z' W Z`` (W diagonal) is

    [[diag(w_p), C], [C', diag(w_s)]],

its diagonal blocks diagonal (the sums of w per participant and per stimulus) and C the
q_p x q_s sums of w per participant and stimulus, sparse: nonzero only where the
participant rated the stimulus. `CrossedBlocks` factorises such a matrix (plus the
identity, scaled by the relative standard deviations) through the Schur complement on
its smaller block: a dense Cholesky of min(q_p, q_s) rows and sparse products with C,
whatever the number of ratings. `analysis.crossed_mixed` (linear) and `analysis.ordinal_mixed`
(cumulative link) build on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pandas as pd
from scipy import linalg, sparse
from scipy import stats as sps

from analysis.errors import AnalysisInputError
from analysis.multiple_comparisons import holm_adjusted


@dataclass(frozen=True)
class CrossedLayout:
    """One cell's ratings as integer codes: ``system`` (0 .. k-1, the reference first),
    ``participant`` and ``stimulus`` (0 .. q-1), with their labels, and ``pair``, the
    index of the rating's (participant, stimulus) among those that occur."""

    systems: list[str]
    participants: np.ndarray
    stimuli: np.ndarray
    system: np.ndarray
    participant: np.ndarray
    stimulus: np.ndarray
    pair: np.ndarray
    pair_participant: np.ndarray
    pair_stimulus: np.ndarray

    def constant_within_systems(self, y: np.ndarray) -> bool:
        """Whether every rating in ``y`` equals its system's mean (nothing varies within a
        system: a mixed model has nothing left to fit)."""
        y = np.asarray(y, dtype=np.float64)
        means = np.bincount(self.system, y) / np.bincount(self.system)
        return bool(np.allclose(y, means[self.system], rtol=0.0, atol=1e-12 * max(1.0, np.abs(y).max())))

    @property
    def q(self) -> tuple[int, int]:
        return len(self.participants), len(self.stimuli)

    def sums(self, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sums of ``weight`` per participant, per stimulus, and per occurring pair."""
        q_p, q_s = self.q
        return (np.bincount(self.participant, weight, q_p), np.bincount(self.stimulus, weight, q_s),
                np.bincount(self.pair, weight, len(self.pair_participant)))

    def cross(self, per_pair: np.ndarray) -> sparse.csr_matrix:
        """The q_p x q_s sparse matrix holding ``per_pair`` at the occurring pairs."""
        return sparse.csr_matrix((per_pair, (self.pair_participant, self.pair_stimulus)), shape=self.q)

    @cached_property
    def indicators(self) -> tuple[sparse.csr_matrix, sparse.csr_matrix]:
        """Z_p' and Z_s' (levels x ratings), to sum the columns of a matrix per level."""
        rows = np.arange(len(self.participant))
        ones = np.ones(len(rows))
        return (sparse.csr_matrix((ones, (self.participant, rows)), shape=(self.q[0], len(rows))),
                sparse.csr_matrix((ones, (self.stimulus, rows)), shape=(self.q[1], len(rows))))

    def by_system(self, factor: np.ndarray, levels: int, weight: np.ndarray | None = None) -> np.ndarray:
        """(levels, systems) sums of ``weight`` (default 1) per level of ``factor`` and system."""
        k = len(self.systems)
        return np.bincount(factor * k + self.system, weight, levels * k).reshape(levels, k)


def crossed_layout(frame: pd.DataFrame, reference: str | None, between: str = "system",
                   participant: str = "participant", stimulus: str = "stimulus") -> CrossedLayout:
    """Code one cell's ratings; the ``reference`` system (default: the first in sorted
    order) becomes system 0."""
    systems = sorted(frame[between].unique())
    if reference is not None:
        if reference not in systems:
            raise AnalysisInputError(f"reference system {reference!r} was not rated here; "
                                     f"systems: {', '.join(map(str, systems))}")
        systems.remove(reference)
        systems.insert(0, reference)
    code = {s: i for i, s in enumerate(systems)}
    participant_code, participants = pd.factorize(frame[participant], sort=True)
    stimulus_code, stimuli = pd.factorize(frame[stimulus], sort=True)
    occurring, pair = np.unique(participant_code.astype(np.int64) * len(stimuli) + stimulus_code,
                                return_inverse=True)
    return CrossedLayout(systems, np.asarray(participants), np.asarray(stimuli),
                         frame[between].map(code).to_numpy(dtype=np.int64),
                         participant_code.astype(np.int64), stimulus_code.astype(np.int64),
                         pair.astype(np.int64), occurring // len(stimuli), occurring % len(stimuli))


class CrossedBlocks:
    """``M = [[diag(a), B], [B', diag(d)]]``, positive definite with B sparse, factorised
    through the Schur complement of its larger diagonal block: ``S = diag(a) - B diag(1/d)
    B'`` when a is the smaller block (the blocks swap otherwise)."""

    def __init__(self, a: np.ndarray, b: sparse.csr_matrix, d: np.ndarray):
        self.swapped = len(d) < len(a)
        if self.swapped:
            a, b, d = d, b.T.tocsr(), a
        self.a, self.b, self.d = a, b, d
        self.b_over_d = b @ sparse.diags(1.0 / d)
        schur = np.diag(a) - (self.b_over_d @ b.T).toarray()
        self.factor = linalg.cho_factor(schur, lower=True, check_finite=False)

    def logdet(self) -> float:
        return float(np.log(self.d).sum() + 2.0 * np.log(np.diag(self.factor[0])).sum())

    def solve(self, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M^{-1} [first; second] as (first block, second block), for vectors or matrices."""
        small, large = (second, first) if self.swapped else (first, second)
        d = self.d if large.ndim == 1 else self.d[:, None]
        x_small = linalg.cho_solve(self.factor, small - self.b_over_d @ large, check_finite=False)
        x_large = (large - self.b.T @ x_small) / d
        return (x_large, x_small) if self.swapped else (x_small, x_large)

    def inverse_blocks(self, rows: np.ndarray, columns: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The diagonals of M^{-1}'s two blocks, and its off-diagonal (q_p x q_s) block's
        entries at (``rows``, ``columns``)."""
        s_inverse = linalg.cho_solve(self.factor, np.eye(len(self.a)), check_finite=False)
        cross = -(self.b_over_d.T @ s_inverse).T  # -S^-1 B D^-1, dense small x large
        large_diagonal = 1.0 / self.d - np.asarray(self.b_over_d.multiply(cross).sum(axis=0)).ravel()
        small_diagonal = np.diag(s_inverse).copy()
        if self.swapped:
            return large_diagonal, small_diagonal, cross[columns, rows]
        return small_diagonal, large_diagonal, cross[rows, columns]


def contrasts_against_reference(estimate: np.ndarray, covariance: np.ndarray, systems: Sequence[str],
                                alpha: float = 0.05, confidence: float = 0.95,
                                effects: bool = False) -> pd.DataFrame:
    """system k minus the reference (system 0) for every other system: difference, se,
    ci_low, ci_high, z, p (two-sided Wald), p_holm (over the contrasts), reject.

    ``effects``: ``estimate`` already holds the differences (the reference's entry 0)."""
    k = len(systems)
    if effects:
        difference, variance = estimate[1:], np.diag(covariance)[1:]
    else:
        difference = estimate[1:] - estimate[0]
        variance = np.diag(covariance)[1:] + covariance[0, 0] - 2 * covariance[0, 1:]
    se = np.sqrt(variance)
    z = difference / se
    p = 2 * sps.norm.sf(np.abs(z))
    half = sps.norm.ppf(0.5 + confidence / 2) * se
    adjusted = holm_adjusted(p)
    return pd.DataFrame({"system": list(systems)[1:], "reference": systems[0], "difference": difference,
                         "se": se, "ci_low": difference - half, "ci_high": difference + half, "z": z,
                         "p": p, "p_holm": adjusted, "reject": adjusted < alpha}) if k > 1 else pd.DataFrame()
