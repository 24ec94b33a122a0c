"""What the crossed random-effects models share: the participant x stimulus layout of a
cell's ratings, the block matrix it gives, and contrasts against a reference system.

Every rating belongs to one participant and one stimulus, so with Z = [Z_p, Z_s] the
indicator matrices of the two factors, any matrix ``Z' W Z`` (W diagonal) is

    [[diag(w_p), C], [C', diag(w_s)]],

its diagonal blocks diagonal (the sums of w per participant and per stimulus) and C the
q_p x q_s sums of w per participant and stimulus, sparse: nonzero only where the
participant rated the stimulus. `CrossedBlocks` factorises such a matrix (plus the
identity, scaled by the relative standard deviations) through the Schur complement on
its smaller block: a dense Cholesky of min(q_p, q_s) rows, and products with C, held
dense when it is compact or as sums over the pairs that occur, whatever the number of
ratings. Which, and the pattern of those sums (`CrossedLayout.pattern`), is worked out
once per layout, since a fit factorises such a matrix hundreds of times with new values
on the same pairs.
`analysis.raters.crossed_mixed` (linear) and `analysis.raters.ordinal_mixed` (cumulative link) build on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pandas as pd
from scipy import linalg
from scipy import stats as sps

from analysis.errors import AnalysisInputError
from analysis.stats.multiple_comparisons import holm_adjusted


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

    @cached_property
    def pattern(self) -> "PairPattern":
        """Where C's entries sit, seen from its smaller block (see `PairPattern`)."""
        return PairPattern.of(self)

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


# C is held dense when its dense products cost at most this many times the multiply-adds
# of a sparse product (BLAS does a dense one many times faster per operation than numpy
# gathers and sums); sparse designs (many participants, few clips each) keep the sums.
_DENSE_ADVANTAGE = 16


@dataclass(frozen=True)
class PairPattern:
    """The occurring (participant, stimulus) pairs as seen from C's smaller block: each
    pair's ``small`` and ``large`` level; C is held dense (``couples`` None) or as sums
    over ``couples``: every ordered couple (first, second) of pairs that share their large
    level, each pair with itself included, whose products make up ``C diag(1/d) C'`` as a
    sparse matrix product visits them (``at`` the couple's entry of the small block)."""

    swapped: bool  # the stimuli are the smaller block
    q_small: int
    q_large: int
    small: np.ndarray
    large: np.ndarray
    couples: tuple[np.ndarray, np.ndarray, np.ndarray] | None  # first, second, at

    @classmethod
    def of(cls, layout: "CrossedLayout") -> "PairPattern":
        q_p, q_s = layout.q
        swapped = q_s < q_p
        q_small, q_large = min(q_p, q_s), max(q_p, q_s)
        small, large = ((layout.pair_stimulus, layout.pair_participant) if swapped
                        else (layout.pair_participant, layout.pair_stimulus))
        counts = np.bincount(large, minlength=q_large)
        if q_small * q_small * q_large <= _DENSE_ADVANTAGE * int(counts @ counts):
            return cls(swapped, q_small, q_large, small, large, None)
        # for each pair, in order of its large level, every pair of that large level
        by_large = np.argsort(large, kind="stable")
        repeat = counts[large[by_large]]
        first = np.repeat(by_large, repeat)
        starts = np.cumsum(counts) - counts
        offset = np.arange(len(first)) - np.repeat(np.cumsum(repeat) - repeat, repeat)
        second = by_large[np.repeat(starts[large[by_large]], repeat) + offset]
        return cls(swapped, q_small, q_large, small, large, (first, second, small[first] * q_small + small[second]))


def _sum_by(index: np.ndarray, values: np.ndarray, levels: int) -> np.ndarray:
    """Sums of ``values`` (a vector, or a matrix of rows) per ``index``."""
    if values.ndim == 1:
        return np.bincount(index, values, levels)
    columns = values.shape[1]
    flat = (index[:, None] * columns + np.arange(columns)).ravel()
    return np.bincount(flat, values.ravel(), levels * columns).reshape(levels, columns)


class CrossedBlocks:
    """``M = [[diag(a), C], [C', diag(d)]]``, positive definite, a participant block ``a``,
    a stimulus block ``d`` and C holding ``per_pair`` at the layout's occurring pairs,
    factorised through the Schur complement of its larger diagonal block: ``S = diag(a) -
    C diag(1/d) C'`` when a is the smaller block (the blocks swap otherwise)."""

    def __init__(self, layout: CrossedLayout, a: np.ndarray, per_pair: np.ndarray, d: np.ndarray):
        pattern = self.pattern = layout.pattern
        if pattern.swapped:
            a, d = d, a
        self.d = d
        self.c_over_d = per_pair / d[pattern.large]
        if pattern.couples is None:
            self.dense_c_over_d = np.zeros((pattern.q_small, pattern.q_large))
            self.dense_c_over_d[pattern.small, pattern.large] = self.c_over_d
            product = (self.dense_c_over_d * d) @ self.dense_c_over_d.T
        else:
            first, second, at = pattern.couples
            product = np.bincount(at, self.c_over_d[first] * per_pair[second],
                                  pattern.q_small**2).reshape(pattern.q_small, pattern.q_small)
        self.factor = linalg.cho_factor(np.diag(a) - product, lower=True, check_finite=False)

    def logdet(self) -> float:
        return float(np.log(self.d).sum() + 2.0 * np.log(np.diag(self.factor[0])).sum())

    def _c_over_d_times(self, large: np.ndarray) -> np.ndarray:
        """C diag(1/d) times a vector or matrix over the large block's levels."""
        pattern = self.pattern
        if pattern.couples is None:
            return self.dense_c_over_d @ large
        weights = self.c_over_d if large.ndim == 1 else self.c_over_d[:, None]
        return _sum_by(pattern.small, weights * large[pattern.large], pattern.q_small)

    def solve(self, first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M^{-1} [first; second] as (first block, second block), for vectors or matrices."""
        pattern = self.pattern
        small, large = (second, first) if pattern.swapped else (first, second)
        x_small = linalg.cho_solve(self.factor, small - self._c_over_d_times(large), check_finite=False)
        # (large - C' x_small) / d = large / d - (C diag(1/d))' x_small
        if pattern.couples is None:
            correction = self.dense_c_over_d.T @ x_small
        else:
            weights = self.c_over_d if large.ndim == 1 else self.c_over_d[:, None]
            correction = _sum_by(pattern.large, weights * x_small[pattern.small], pattern.q_large)
        x_large = (large / (self.d if large.ndim == 1 else self.d[:, None])) - correction
        return (x_large, x_small) if pattern.swapped else (x_small, x_large)

    def inverse_blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The diagonals of M^{-1}'s participant and stimulus blocks, and its off-diagonal
        block's entry at each occurring pair (the layout's ``pair_participant``,
        ``pair_stimulus``)."""
        pattern = self.pattern
        s_inverse = linalg.cho_solve(self.factor, np.eye(pattern.q_small), check_finite=False)
        # the off-diagonal block is -S^-1 C diag(1/d); wanted at the occurring pairs only
        if pattern.couples is None:
            cross = -(s_inverse @ self.dense_c_over_d)[pattern.small, pattern.large]
        else:
            first, second, _ = pattern.couples
            cross = -np.bincount(first, s_inverse[pattern.small[first], pattern.small[second]]
                                 * self.c_over_d[second], len(self.c_over_d))
        # the large block is diag(1/d) + (C diag(1/d))' S^-1 C diag(1/d)
        large_diagonal = 1.0 / self.d - np.bincount(pattern.large, self.c_over_d * cross, pattern.q_large)
        small_diagonal = np.diag(s_inverse).copy()
        if pattern.swapped:
            return large_diagonal, small_diagonal, cross
        return small_diagonal, large_diagonal, cross


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
