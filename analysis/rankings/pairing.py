"""Adaptive pairing: which two systems a pairwise study shows next, and on which sides.

The next pair is the one whose vote is expected to tell most about the ranking under
the current fit, with a floor of uniform exploration and the sides balanced per pair.

Current fit. The weighted Bradley-Terry model of `analysis.rankings.leaderboard` on the votes so
far (2 wins per degree of preference, a plain one 4, no preference 1 for each side), plus a weak prior of
``PRIOR_TIES`` page without preference per pair, so that a fit exists from the first
vote and a system that has not lost yet is not placed at infinity.

Information. A page of pair (i, j) is one comparison with ``p = sigmoid(b_i - b_j)``;
its Fisher information about the log-strengths ``b`` is ``w a a'`` with ``w = p (1 - p)``
and ``a = e_i - e_j``. With ``I`` the information of the pages shown so far (the prior's
pages included), the leaderboard's uncertainty is the covariance ``C`` of the
log-strengths relative to the anchor (``I`` without the anchor's row and column,
inverted; without an anchor, the centred strengths and ``I``'s pseudo-inverse).

Criterion. The next pair is the one whose vote is expected to improve the leaderboard
most on both of its promises at once, its intervals and its order: the smallest product of

- the sum of the systems' standard errors after one more page of it, and
- the expected number of pairs of systems it then orders against the truth (Kendall's
  tau with the true order is one minus twice their share),

so a page is worth the share it takes off either. By Sherman-Morrison the covariance
after a page of pair c is ``C - w_c (C a_c)(C a_c)' / (1 + w_c a_c' C a_c)``, for every
candidate at once from one (systems x pairs) product. For the order, let ``Delta = a_d' b``
be the difference of the two systems of pair d: now ``Delta ~ N(m, s^2)`` (``m`` its
fitted value, ``s^2 = a_d' C a_d``) and after the page its variance is ``s'^2``. Seen from
now, the fitted difference after the page is ``m' ~ N(m, t^2)`` with ``t^2 = s^2 - s'^2``,
and ``Cov(m', Delta) = t^2`` (the usual Gaussian update: ``Delta - m'`` is independent of
``m'``). The probability that the fit after the page orders the pair against the truth is

    P(sign m' != sign Delta) = 2 T(|m| / s, s' / t),

with Owen's T function. Derivation: (m', Delta) are bivariate normal with correlation
``rho = t / s``; with ``h = m / t`` and ``k = m / s = rho h``, the chance of opposite signs
is ``Phi(h) + Phi(k) - 2 Phi_2(h, k; rho)``, and Owen's formula
``Phi_2(h, k; rho) = (Phi(h) + Phi(k)) / 2 - T(h, (k - rho h) / (h r)) - T(k, (h - rho k) / (k r))``
(``r = sqrt(1 - rho^2)``, h and k of one sign) loses its first T since ``k = rho h``; the
second is ``T(k, r / rho) = T(m / s, s' / t)``. With ``m = 0`` this is
``arctan(s' / t) / pi``; with ``t = 0``, a page that says nothing about the pair, it is
today's ``Phi(-|m| / s)``. Unlike the plug-in ``Phi(-|m| / s')``, which is flat where
two systems look level (``m = 0``), it falls most for the pairs that look level and are
not settled, the pairs whose order is in doubt. Summed over the pairs it is what a page
is expected to leave of the misorders.

Votes go where they are informative (close systems, p near 1/2), to the pairs that tie
the systems to the anchor, and to close neighbours whose order is open; a pair whose
outcome is a foregone conclusion (p near 0 or 1) is rarely shown. Simulated on 10
systems (`analysis.reports.pairing_simulation`, the README's table), the votes it saves against
uniform pairing, for interval width and Kendall's tau at once, come within a few points
of what the best fixed allocation for the true strengths saves (the ceiling of any
pairing) from about 75 participants on: 30-36 % where the systems spread over 900 Elo or
more.

Exploration. With probability ``exploration`` (default 0.1, the documented epsilon) the
pair is drawn uniformly instead, so every pair keeps being shown and a wrong early
fit is corrected by data it did not ask for.

Sides. Of the chosen pair, the system shown on the left less often against the other
goes left; at equal counts a coin decides. Over a study every pair is balanced within
one page.

Several pages at once. A study app plans a participant's pages when they enrol, before
any of them is answered: `plan_pairs` fits the votes once and chooses the pages one
after another, each counting as shown for the next (its information about the ranking
and its side, not a vote), as do the pages other participants hold unanswered; with
``pages=1`` it is `next_pair`. `plan_pages` does the same on a `PairingState` (the
simulation's participants are planned with it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.special import owens_t

from analysis.blas import one_blas_thread
from analysis.pages import NO_PREFERENCE
from analysis.errors import AnalysisInputError
from analysis.rankings.leaderboard import TIE_WEIGHT, bradley_terry_log_strengths, vote_weights

EXPLORATION = 0.1
PRIOR_TIES = 1.0
_VOTE_COLUMNS = ("system_left", "system_right", "answer")


@dataclass
class PairingState:
    """What the pairing needs of the votes so far, per ordered pair of the ``systems``:
    ``wins[i, j]`` the weighted wins of i over j (ties' credits included), ``shown[i, j]``
    the pages of the pair (symmetric) and ``left[i, j]`` those with i on the left."""

    systems: list[str]
    wins: np.ndarray
    shown: np.ndarray
    left: np.ndarray

    @classmethod
    def empty(cls, systems: Sequence[str]) -> PairingState:
        k = len(systems)
        return cls(list(systems), np.zeros((k, k)), np.zeros((k, k)), np.zeros((k, k)))

    def hand_out(self, left: int, right: int) -> None:
        """Count one page shown, answered or not: ``left`` and ``right`` index the systems."""
        self.shown[left, right] += 1
        self.shown[right, left] += 1
        self.left[left, right] += 1

    def add(self, left: int, right: int, answer: str, weight: float) -> None:
        """Count one answered page: ``left`` and ``right`` index the systems."""
        self.hand_out(left, right)
        self.answer(left, right, answer, weight)

    def answer(self, left: int, right: int, answer: str, weight: float) -> None:
        """Count the answer of a page already handed out."""
        if answer == NO_PREFERENCE:
            self.wins[left, right] += weight
            self.wins[right, left] += weight
        elif answer == "left":
            self.wins[left, right] += weight
        else:
            self.wins[right, left] += weight


def pairing_state(votes: pd.DataFrame, systems: Sequence[str]) -> PairingState:
    """The state of the votes so far: one row per page with ``system_left``,
    ``system_right``, ``answer`` (left / right / none) and optionally ``strength``."""
    missing = [c for c in _VOTE_COLUMNS if c not in votes.columns]
    if missing:
        raise AnalysisInputError(f"the votes lack the column(s) {', '.join(missing)}; one row per "
                                 f"page needs {', '.join(_VOTE_COLUMNS)} and optionally strength")
    state = PairingState.empty(systems)
    where = {s: i for i, s in enumerate(state.systems)}
    unknown = sorted((set(votes["system_left"]) | set(votes["system_right"])) - set(where))
    if unknown:
        raise AnalysisInputError(f"the votes name system(s) {', '.join(map(str, unknown))} that are "
                                 f"not among the systems {', '.join(state.systems)}")
    strength = votes["strength"] if "strength" in votes.columns else pd.Series(pd.NA, index=votes.index)
    weights = vote_weights(votes["answer"], strength)
    for left, right, answer, weight in zip(votes["system_left"].map(where), votes["system_right"].map(where),
                                           votes["answer"], weights):
        state.add(left, right, answer, weight)
    return state


def current_fit(state: PairingState, start: np.ndarray | None = None) -> np.ndarray:
    """Log-strengths (system 0 at 0) of the votes so far with the prior's pages."""
    prior = PRIOR_TIES * TIE_WEIGHT * (1.0 - np.eye(len(state.systems)))
    return bradley_terry_log_strengths(state.wins + prior, start)


def pair_incidence(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs i < j of ``k`` systems (``np.triu_indices`` order) and their rows
    ``a = e_i - e_j``, one per pair."""
    first, second = np.triu_indices(k, 1)
    incidence = np.zeros((len(first), k))
    incidence[np.arange(len(first)), first], incidence[np.arange(len(first)), second] = 1.0, -1.0
    return first, second, incidence


def comparison_information(log_strength: np.ndarray, first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Per pair: the Fisher information ``p (1 - p)`` of one comparison, ``p = sigmoid(b_i - b_j)``."""
    p = 0.5 * (1.0 + np.tanh((log_strength[first] - log_strength[second]) / 2))
    return p * (1 - p)


@dataclass
class PageEffect:
    """What one more page of each candidate pair c would do to the fit's uncertainty:
    ``page_information[c]`` is the information ``w_c`` of one page of it, ``covariance``
    the covariance C of the log-strengths (relative to the anchor, or centred),
    ``spread[:, c]`` is ``C a_c``, ``variance[d]`` the variance ``a_d' C a_d`` of pair d's
    difference now and ``variance_after[d, c]`` that variance after one more page of c
    (pairs and candidates in ``np.triu_indices`` order)."""

    page_information: np.ndarray
    covariance: np.ndarray
    spread: np.ndarray
    variance: np.ndarray
    variance_after: np.ndarray


def page_effect(state: PairingState, log_strength: np.ndarray, anchor: int | None) -> PageEffect:
    """`PageEffect` of the pages shown so far (the prior's included), by Sherman-Morrison."""
    first, second, incidence = pair_incidence(len(state.systems))
    w = comparison_information(log_strength, first, second)
    pages = state.shown[first, second] + PRIOR_TIES
    information = incidence.T @ ((pages * w)[:, None] * incidence)
    if anchor is None:
        covariance = np.linalg.pinv(information, hermitian=True)
    else:
        incidence = np.delete(incidence, anchor, axis=1)
        covariance = np.linalg.inv(np.delete(np.delete(information, anchor, 0), anchor, 1))
    spread = covariance @ incidence.T
    between = incidence @ spread  # [d, c]: a_d' C a_c
    variance = np.diag(between).copy()
    after = variance[:, None] - w * between**2 / (1.0 + w * variance)
    return PageEffect(w, covariance, spread, variance, np.maximum(after, 0.0))


def expected_standard_errors(state: PairingState, log_strength: np.ndarray,
                             anchor: int | None, effect: PageEffect | None = None) -> np.ndarray:
    """Per candidate pair (i < j, in ``np.triu_indices`` order): the sum of the systems'
    standard errors (log-odds, relative to ``anchor`` or centred) after one more page of it."""
    effect = page_effect(state, log_strength, anchor) if effect is None else effect
    w, spread = effect.page_information, effect.spread
    after = np.diag(effect.covariance)[:, None] - w * spread**2 / (1.0 + w * effect.variance)
    return np.sqrt(np.maximum(after, 0.0)).sum(axis=0)


def expected_misorders(state: PairingState, log_strength: np.ndarray,
                       effect: PageEffect | None = None) -> np.ndarray:
    """Per candidate pair (``np.triu_indices`` order): the expected number of pairs of
    systems that the fit after one more page of it orders against the truth, under the
    current fit, ``sum over d of 2 T(|m_d| / s_d, s'_dc / t_dc)`` (module docstring)."""
    # a difference's variance is the same whichever system is fixed: any anchor will do
    effect = page_effect(state, log_strength, 0) if effect is None else effect
    first, second = np.triu_indices(len(state.systems), 1)
    gap = np.abs(log_strength[first] - log_strength[second])[:, None]
    s = np.sqrt(effect.variance)[:, None]
    settled = np.maximum(effect.variance[:, None] - effect.variance_after, 0.0)  # t^2
    with np.errstate(divide="ignore"):  # t = 0: the page says nothing of the pair, T(h, inf)
        slope = np.sqrt(effect.variance_after / settled)
    return 2.0 * owens_t(gap / s, slope).sum(axis=0)


def pair_scores(state: PairingState, log_strength: np.ndarray, anchor: int | None) -> np.ndarray:
    """Per candidate pair: the criterion, the log of the product of `expected_standard_errors`
    and `expected_misorders` (the smallest is shown)."""
    effect = page_effect(state, log_strength, anchor)
    errors = expected_standard_errors(state, log_strength, anchor, effect)
    misorders = expected_misorders(state, log_strength, effect)
    # once every order is certain to the last float, the intervals alone decide
    return np.log(errors) + np.log(np.maximum(misorders, np.finfo(np.float64).tiny))


def choose_pair(state: PairingState, rng: np.random.Generator, exploration: float = EXPLORATION,
                anchor: int | None = None, log_strength: np.ndarray | None = None,
                allowed: np.ndarray | None = None) -> tuple[int, int]:
    """(left, right) indices of the next page; ``anchor`` indexes the system the
    leaderboard fixes (None: centred), ``log_strength`` the current fit (default:
    `current_fit`), ``allowed`` the pairs (``np.triu_indices`` order) that may be shown
    (default: every pair; exploration draws among them too)."""
    if not 0.0 <= exploration <= 1.0:
        raise AnalysisInputError(f"exploration must lie in [0, 1]; got {exploration}")
    k = len(state.systems)
    if k < 2:
        raise AnalysisInputError("pairing needs at least two systems")
    first, second = np.triu_indices(k, 1)
    candidates = np.arange(len(first)) if allowed is None else np.flatnonzero(allowed)
    if not len(candidates):
        raise AnalysisInputError("no pair of systems may be shown")
    if rng.random() < exploration:
        chosen = rng.choice(candidates)
    else:
        b = current_fit(state) if log_strength is None else log_strength
        scores = pair_scores(state, b, anchor)[candidates]
        chosen = rng.choice(candidates[scores <= scores.min() + 1e-12 * max(1.0, abs(scores.min()))])
    i, j = int(first[chosen]), int(second[chosen])
    i_left, j_left = state.left[i, j], state.left[j, i]
    if i_left > j_left or (i_left == j_left and rng.random() < 0.5):
        i, j = j, i
    return i, j


def next_pair(votes: pd.DataFrame, systems: Sequence[str], rng: np.random.Generator,
              exploration: float = EXPLORATION, anchor: str | None = "NAT") -> tuple[str, str]:
    """The (left, right) systems of the next pairwise page, given the votes so far (one
    row per page: ``system_left``, ``system_right``, ``answer``, optionally ``strength``).

    ``anchor`` is the system the leaderboard fixes at Elo 1000; when it is not among the
    ``systems`` (or None) the leaderboard's centred scale is what the pairing sharpens.
    """
    return plan_pairs(votes, systems, 1, rng, exploration, anchor)[0]


def plan_pairs(votes: pd.DataFrame, systems: Sequence[str], pages: int, rng: np.random.Generator,
               exploration: float = EXPLORATION, anchor: str | None = "NAT",
               held: pd.DataFrame | None = None,
               capacity: Mapping[frozenset[str], int] | None = None) -> list[tuple[str, str]]:
    """The (left, right) systems of the next ``pages`` pages, chosen one after another as
    `next_pair` chooses one, from one fit of the ``votes`` so far: a page planned counts as
    shown (its information and its side) for the pages after it, but adds no vote, since
    its answer is not known yet. ``held`` are pages handed out and not answered yet (rows
    of ``system_left``, ``system_right``), counted the same way. ``capacity`` says how many
    more pages each pair of systems may take (a pair missing from it: none); the plan stops
    early when no pair may take more.
    """
    if len(systems) < 2:
        raise AnalysisInputError("pairing needs at least two systems")
    if not 0.0 <= exploration <= 1.0:
        raise AnalysisInputError(f"exploration must lie in [0, 1]; got {exploration}")
    state = pairing_state(votes, systems)
    where = {s: i for i, s in enumerate(state.systems)}
    for left, right in ([] if held is None else zip(held["system_left"], held["system_right"])):
        state.hand_out(where[left], where[right])
    first, second = np.triu_indices(len(state.systems), 1)
    room = (np.full(len(first), pages) if capacity is None else
            np.array([capacity.get(frozenset((state.systems[i], state.systems[j])), 0)
                      for i, j in zip(first, second)]))
    fixed = state.systems.index(anchor) if anchor in state.systems else None
    with one_blas_thread():
        planned = plan_pages(state, pages, rng, exploration, fixed, room=room)
    return [(state.systems[left], state.systems[right]) for left, right in planned]


def plan_pages(state: PairingState, pages: int, rng: np.random.Generator, exploration: float = EXPLORATION,
               anchor: int | None = None, log_strength: np.ndarray | None = None,
               room: np.ndarray | None = None) -> list[tuple[int, int]]:
    """`plan_pairs` on a `PairingState`: the (left, right) indices of the next ``pages``
    pages from one fit (``log_strength``, default `current_fit`), each handed out on
    ``state`` as it is planned. ``room`` (per pair, ``np.triu_indices`` order; default no
    limit) is how many more pages each pair may take, and is used up."""
    first, second = np.triu_indices(len(state.systems), 1)
    room = np.full(len(first), pages) if room is None else room
    pair_of = {(i, j): c for c, (i, j) in enumerate(zip(first, second))}
    fit = current_fit(state) if log_strength is None else log_strength
    planned = []
    while len(planned) < pages and room.any():
        left, right = choose_pair(state, rng, exploration, anchor, fit, allowed=room > 0)
        room[pair_of[min(left, right), max(left, right)]] -= 1
        state.hand_out(left, right)
        planned.append((left, right))
    return planned
