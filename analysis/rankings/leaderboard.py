"""A leaderboard from pairwise votes: weighted Bradley-Terry on an Elo scale with
bootstrap intervals, as the GENEA leaderboard (Nagy et al. 2024) and Chatbot Arena report.

Votes. A pairwise page shows two systems' clips and is answered ``left``, ``right`` or
``none`` (no preference), a stated preference optionally with a ``strength``: a degree of
preference from 1 (slightly better) up to as many degrees as the study asked; GENEA's five
levels are two degrees, 1 = slightly, 2 = clearly (docs/ratings-schema.md). Each page
becomes weighted wins:

- a preference of strength k counts 2k wins of the preferred system: GENEA's slight win 2
  and clear win 4, and with more degrees each one 2 more (a three-degree study's 2, 4, 6);
- a preference without a strength (the plain left / right / none page) counts as GENEA's
  clear one, 4 wins, so plain tables give the ordinary Bradley-Terry fit;
- "no preference" counts 1 win for each side (a tie is half of a slight preference each way).

The rule needs no count of degrees: a table does not say how many the study offered, and
a level means the same wins whichever of the study's degrees were used.

Models (``model``):

- ``bradley-terry`` (default): ``P(i beats j) = sigmoid(b_i - b_j)``, fitted by maximising
  ``sum w log sigmoid(b_winner - b_loser)`` over the weighted wins: the likelihood of a
  logistic regression with frequency weights (the tests check it against statsmodels'
  GLM with ``freq_weights``).
- ``davidson`` (Davidson 1970): ties are an outcome of their own, ``P(i beats j) = pi_i /
  D``, ``P(tie) = nu sqrt(pi_i pi_j) / D``, ``D = pi_i + pi_j + nu sqrt(pi_i pi_j)``, with
  ``pi = exp(b)``; a page keeps its weight (2 per degree of strength, a tie 2 = 1 for each side),
  and ``nu`` (reported as ``tie_parameter``) is fitted with the strengths.

Both log-likelihoods are concave (a weighted sum of log-sum-exps of linear functions, negated),
so Newton's method with step halving finds the maximum when it exists: when the graph
with an arrow i -> j for every win of i over j (ties point both ways) is strongly
connected, and for Davidson when some pages are ties and some are not. Otherwise a
system's strength is unbounded and the cell is left out with a note.

Scale. ``elo = 1000 + 400 (b - b_anchor) / ln 10``: the anchor (default the natural
motion, NAT, when it was compared) sits at 1000, and 400 Elo points are odds of 10 to 1.
Without an anchor the systems' mean sits at 1000.

Intervals. Weighted wins are not counts of independent events and one participant's
votes depend on each other, so the Fisher information does not give the error. The
intervals are percentiles of a bootstrap over participants (default 10,000 resamples,
seeded): a resample draws as many participants as were kept, with replacement, and
refits. All resamples are fitted at once: a resample is a vector of multinomial counts
of participants, its pair totals one matrix product, and Newton's method runs on every
resample together from the full data's fit, a few batched 7 x 7 solves for 8 systems.
A resample in which the maximum does not exist (a system that never lost, say) cannot
be refitted; it is left out and counted in ``resamples_used``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.blas import one_blas_thread
from analysis.rankings.bradley_terry import never_compared_reason
from analysis.pages import NO_PREFERENCE, PAGE
from analysis.errors import AnalysisInputError
from analysis.stats.minimums import INTERVAL_FEW_PARTICIPANTS, few_participants_warning, too_few_for_bootstrap
from analysis.stats.preferences import preference_pages
from analysis.stats.anova import CELL, iter_cells

CLEAR, SLIGHT = 2, 1  # GENEA's degrees of preference
WINS_PER_DEGREE = 2.0  # a preference of strength k counts 2k wins: slight 2, clear 4
PLAIN_WIN_WEIGHT = WINS_PER_DEGREE * CLEAR  # a preference without a strength counts as clear
TIE_WEIGHT = 1.0  # credited to each side of a page without preference
BRADLEY_TERRY, DAVIDSON = "bradley-terry", "davidson"
MODELS = (BRADLEY_TERRY, DAVIDSON)
ELO_BASE = 1000.0
ELO_PER_LOG_ODDS = 400.0 / np.log(10.0)
RESAMPLES = 10_000
# A bootstrap over fewer participants than this draws from so few distinct resamples that
# its percentiles understate the uncertainty; such intervals are flagged, not hidden.
INTERVAL_WARNING_PARTICIPANTS = INTERVAL_FEW_PARTICIPANTS

_STEP_TOLERANCE = 1e-10
_CHUNK = 2_000
_MAX_NEWTON_STEPS = 200


def vote_pages(kept: pd.DataFrame, groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """One row per page of a pairwise table (`analysis.stats.preferences.preference_pages`) with
    its ``strength`` (nullable) and ``weight``: the wins credited to the preferred system
    (2 per degree of strength, 4 for a plain preference), or to each side of a page without
    preference (1).

    Raises AnalysisInputError for a strength that is not a whole number from 1.
    """
    pages = preference_pages(kept, groupby)
    keys = [*dict.fromkeys([*groupby, *PAGE])]
    if "strength" in kept.columns:
        strength = pd.to_numeric(kept["strength"], errors="coerce")
        beyond = kept["strength"].notna() & ~((strength >= 1) & (strength % 1 == 0))
        if beyond.any():
            row = int(kept.index[beyond.to_numpy()][0]) + 1
            raise AnalysisInputError(
                f"column 'strength' must be a whole number from 1 (slightly better) for the "
                f"leaderboard; row {row} holds {kept.loc[beyond, 'strength'].iloc[0]}")
        strength = strength.astype("Int64")
        left = kept.loc[kept["side"] == "left", keys].assign(strength=strength)
        pages = pages.merge(left, on=keys, how="left")
    else:
        pages["strength"] = pd.array([pd.NA] * len(pages), dtype="Int64")
    pages["weight"] = vote_weights(pages["answer"], pages["strength"])
    return pages


def vote_weights(answer: pd.Series, strength: pd.Series) -> np.ndarray:
    """The wins a page credits to its preferred system (2 per degree of strength, 4 without
    a strength), or to each side when answered ``none`` (1)."""
    weight = (WINS_PER_DEGREE * pd.to_numeric(pd.Series(strength), errors="coerce")).astype("float64")
    return np.where(pd.Series(answer).to_numpy() == NO_PREFERENCE, TIE_WEIGHT,
                    weight.fillna(PLAIN_WIN_WEIGHT).to_numpy())


@dataclass(frozen=True)
class PairVotes:
    """The votes of one cell per participant and pair of systems.

    ``first`` and ``second`` index ``systems`` (every pair, first < second); the arrays are
    (participants, pairs): ``won`` and ``lost`` the weighted wins of the first system over
    the second and of the second over the first, ``tied`` the pages without preference,
    ``pages`` all pages of the pair.
    """

    systems: list[str]
    first: np.ndarray
    second: np.ndarray
    won: np.ndarray
    lost: np.ndarray
    tied: np.ndarray
    pages: np.ndarray

    def totals(self, counts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(won, lost, tied) summed over participants, each (pairs,); or per resample
        (resamples, pairs) for ``counts`` (resamples, participants) of each participant."""
        if counts is None:
            return self.won.sum(axis=0), self.lost.sum(axis=0), self.tied.sum(axis=0)
        return counts @ self.won, counts @ self.lost, counts @ self.tied


def pair_votes(pages: pd.DataFrame, systems: Sequence[str] | None = None) -> PairVotes:
    """`vote_pages` of one cell as `PairVotes` (systems sorted unless given)."""
    systems = list(systems) if systems is not None else sorted(
        set(pages["system_left"]) | set(pages["system_right"]))
    where = {s: i for i, s in enumerate(systems)}
    k = len(systems)
    first, second = np.triu_indices(k, 1)
    pair_of = np.full((k, k), -1)
    pair_of[first, second] = pair_of[second, first] = np.arange(len(first))
    participant, _ = pd.factorize(pages["participant"])
    left = pages["system_left"].map(where).to_numpy(dtype=int)
    right = pages["system_right"].map(where).to_numpy(dtype=int)
    pair = pair_of[left, right]
    left_is_first = left < right
    answer = pages["answer"].to_numpy()
    weight = pages["weight"].to_numpy(dtype=np.float64)
    first_won = np.where(left_is_first, answer == "left", answer == "right")
    second_won = np.where(left_is_first, answer == "right", answer == "left")
    shape = (participant.max() + 1 if len(participant) else 0, len(first))
    arrays = {name: np.zeros(shape) for name in ("won", "lost", "tied", "pages")}
    np.add.at(arrays["won"], (participant, pair), weight * first_won)
    np.add.at(arrays["lost"], (participant, pair), weight * second_won)
    np.add.at(arrays["tied"], (participant, pair), (answer == NO_PREFERENCE).astype(np.float64))
    np.add.at(arrays["pages"], (participant, pair), 1.0)
    return PairVotes(systems, first, second, **arrays)


def _incidence(first: np.ndarray, second: np.ndarray, k: int) -> np.ndarray:
    """(pairs, k - 1): d = b_first - b_second in the free strengths (system 0 fixed at 0)."""
    a = np.zeros((len(first), k))
    a[np.arange(len(a)), first] = 1.0
    a[np.arange(len(a)), second] = -1.0
    return a[:, 1:]


def _softplus(x):
    return np.logaddexp(0.0, x)


class _PairLikelihood:
    """Per-pair log-likelihood and derivatives in d = b_first - b_second (and log nu)."""

    def __init__(self, model: str, won: np.ndarray, lost: np.ndarray, tied: np.ndarray):
        self.davidson = model == DAVIDSON
        if self.davidson:
            self.first, self.second, self.ties = won, lost, 2.0 * TIE_WEIGHT * tied
        else:
            self.first, self.second, self.ties = won + TIE_WEIGHT * tied, lost + TIE_WEIGHT * tied, 0.0 * tied
        self.total = self.first + self.second + self.ties

    def value(self, d: np.ndarray, log_nu: np.ndarray | None) -> np.ndarray:
        if not self.davidson:
            return (-self.first * _softplus(-d) - self.second * _softplus(d)).sum(axis=-1)
        log_d = np.logaddexp(np.logaddexp(d / 2, -d / 2), log_nu[:, None])
        return ((self.first - self.second) * d / 2 + self.ties * log_nu[:, None]
                - self.total * log_d).sum(axis=-1)

    def derivatives(self, d: np.ndarray, log_nu: np.ndarray | None):
        """dl/dd, d2l/dd2 per pair, and for Davidson dl/dlognu, d2l/dd dlognu, d2l/dlognu2."""
        if not self.davidson:
            p = 0.5 * (1.0 + np.tanh(d / 2))
            return self.first - self.total * p, -self.total * p * (1 - p), None, None, None
        log_d = np.logaddexp(np.logaddexp(d / 2, -d / 2), log_nu[:, None])
        p_first, p_second = np.exp(d / 2 - log_d), np.exp(-d / 2 - log_d)
        p_tie = np.exp(log_nu[:, None] - log_d)
        half_gap = (p_first - p_second) / 2
        return ((self.first - self.second) / 2 - self.total * half_gap,
                -self.total * ((p_first + p_second) / 4 - half_gap**2),
                self.ties - self.total * p_tie,
                self.total * half_gap * p_tie,
                -self.total * p_tie * (1 - p_tie))


def _fit_batch(model: str, incidence: np.ndarray, won: np.ndarray, lost: np.ndarray,
               tied: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Maximum-likelihood parameters (free strengths, then log nu for Davidson) for every
    row of the (batch, pairs) totals, by Newton's method with step halving."""
    likelihood = _PairLikelihood(model, won, lost, tied)
    free = incidence.shape[1]
    theta = start.copy()
    if not len(theta):
        return theta

    def split(t):
        return t[:, :free] @ incidence.T, (t[:, free] if likelihood.davidson else None)

    current = likelihood.value(*split(theta))
    for _ in range(_MAX_NEWTON_STEPS):
        g_d, h_dd, g_nu, h_dnu, h_nunu = likelihood.derivatives(*split(theta))
        gradient = g_d @ incidence
        hessian = (incidence.T[None] * h_dd[:, None, :]) @ incidence
        if likelihood.davidson:
            gradient = np.concatenate([gradient, g_nu.sum(axis=1, keepdims=True)], axis=1)
            cross = h_dnu @ incidence
            hessian = np.block([[hessian, cross[:, :, None]],
                                [cross[:, None, :], h_nunu.sum(axis=1)[:, None, None]]])
        step = np.linalg.solve(-hessian, gradient[..., None])[..., 0]
        scale = np.ones(len(theta))
        for _ in range(60):
            trial = theta + scale[:, None] * step
            value = likelihood.value(*split(trial))
            worse = value < current - 1e-12 * np.abs(current)
            if not worse.any():
                break
            scale[worse] /= 2
        theta, current = trial, value
        if np.abs(scale[:, None] * step).max() < _STEP_TOLERANCE:
            return theta
    raise AnalysisInputError(f"the {model} fit did not converge in {_MAX_NEWTON_STEPS} Newton steps")


def _estimable(model: str, votes: PairVotes, won: np.ndarray, lost: np.ndarray,
               tied: np.ndarray) -> np.ndarray:
    """Per row of the (batch, pairs) totals: whether the maximum-likelihood fit exists."""
    k = len(votes.systems)
    beats = np.zeros((len(won), k, k))
    beats[:, votes.first, votes.second] = (won + tied) > 0
    beats[:, votes.second, votes.first] = (lost + tied) > 0
    reach = beats + np.eye(k)
    for _ in range(int(np.ceil(np.log2(max(k, 2))))):
        reach = ((reach @ reach) > 0).astype(np.float64)
    connected = (reach > 0).all(axis=(1, 2)) & (k >= 2)
    if model == DAVIDSON:
        connected &= (tied.sum(axis=1) > 0) & ((won + lost).sum(axis=1) > 0)
    return connected


def _not_estimable_reason(model: str, votes: PairVotes) -> str:
    won, lost, tied = votes.totals()
    k = len(votes.systems)
    if k < 2:
        return "fewer than two systems were compared"
    if model == DAVIDSON and not tied.any():
        return ("no page was answered 'no preference', so Davidson's tie parameter is zero; "
                "the weighted Bradley-Terry model fits such votes")
    if model == DAVIDSON and not (won + lost).any():
        return "every page was answered 'no preference'"
    compared = np.zeros((k, k), dtype=bool)
    compared[votes.first, votes.second] = votes.pages.sum(axis=0) > 0
    apart = never_compared_reason(compared, votes.systems)
    if apart:
        return apart
    lost_any, won_any = np.zeros(k), np.zeros(k)
    np.add.at(won_any, votes.first, won + tied)
    np.add.at(won_any, votes.second, lost + tied)
    np.add.at(lost_any, votes.first, lost + tied)
    np.add.at(lost_any, votes.second, won + tied)
    never_lost = [votes.systems[i] for i in np.flatnonzero(lost_any == 0)]
    never_won = [votes.systems[i] for i in np.flatnonzero(won_any == 0)]
    if never_lost or never_won:
        return (f"{', '.join(never_lost) or 'no system'} never lost and {', '.join(never_won) or 'no system'} "
                "never won a vote, so their strengths are unbounded")
    return ("the systems fall into groups of which one always beat the other (they were compared, but the "
            "other group never won), so the groups' distance is unbounded")


def _start(model: str, votes: PairVotes, rows: int) -> np.ndarray:
    free = len(votes.systems) - 1
    start = np.zeros((rows, free + (model == DAVIDSON)))
    if model == DAVIDSON:
        won, lost, tied = votes.totals()
        share = 2 * TIE_WEIGHT * tied.sum() / (won.sum() + lost.sum() + 2 * TIE_WEIGHT * tied.sum())
        start[:, free] = np.log(2 * share / (1 - share))  # nu at equal strengths
    return start


@dataclass(frozen=True)
class Fit:
    """One cell's fit: log-strengths ``b`` (system 0 at 0), the tie parameter (Davidson)
    and, from the bootstrap, the resampled log-strengths (resamples used, systems)."""

    systems: list[str]
    model: str
    log_strength: np.ndarray
    tie_parameter: float
    resampled: np.ndarray
    resamples: int


def resample_chunks(participants: int, resamples: int, seed: int):
    """(chunk, participants) arrays, ``_CHUNK`` resamples at a time: how often each
    participant is drawn into each resample (a chunk keeps memory small for many participants)."""
    rng = np.random.default_rng(seed)
    share = np.full(participants, 1.0 / participants)
    for start in range(0, resamples, _CHUNK):
        yield rng.multinomial(participants, share, size=min(_CHUNK, resamples - start)).astype(np.float64)


def participant_resamples(participants: int, resamples: int, seed: int) -> np.ndarray:
    """(resamples, participants): every chunk of `resample_chunks` at once."""
    return np.vstack(list(resample_chunks(participants, resamples, seed)))


def fit_votes(votes: PairVotes, model: str = BRADLEY_TERRY, resamples: int = RESAMPLES,
              seed: int = 0) -> Fit:
    """Fit ``model`` to one cell's votes and to ``resamples`` bootstrap resamples of its
    participants. Raises AnalysisInputError when the full data's maximum does not exist."""
    if model not in MODELS:
        raise AnalysisInputError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    incidence = _incidence(votes.first, votes.second, len(votes.systems))
    totals = [t[None] for t in votes.totals()]
    if not _estimable(model, votes, *totals)[0]:
        raise AnalysisInputError(_not_estimable_reason(model, votes))
    theta = _fit_batch(model, incidence, *totals, _start(model, votes, 1))[0]
    free = len(votes.systems) - 1
    refits = [np.empty((0, free))]
    for counts in resample_chunks(len(votes.won), resamples, seed):
        drawn = votes.totals(counts)
        usable = _estimable(model, votes, *drawn)
        refit = _fit_batch(model, incidence, *(t[usable] for t in drawn),
                           np.repeat(theta[None], usable.sum(), axis=0))
        refits.append(refit[:, :free])
    refit = np.concatenate(refits)
    resampled = np.concatenate([np.zeros((len(refit), 1)), refit], axis=1)
    return Fit(votes.systems, model, np.r_[0.0, theta[:free]],
               float(np.exp(theta[free])) if model == DAVIDSON else np.nan, resampled, resamples)


def bradley_terry_log_strengths(wins: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
    """Weighted Bradley-Terry log-strengths (system 0 at 0) from ``wins[i, j]``, the
    weighted wins of i over j, ties' credits included; ``start`` (system 0 at 0) is where
    Newton's method begins. The maximum must exist (see the module's docstring)."""
    k = len(wins)
    first, second = np.triu_indices(k, 1)
    begin = np.zeros((1, k - 1)) if start is None else np.asarray(start, dtype=np.float64)[None, 1:]
    theta = _fit_batch(BRADLEY_TERRY, _incidence(first, second, k), wins[first, second][None],
                       wins[second, first][None], np.zeros((1, len(first))), begin)
    return np.r_[0.0, theta[0]]


def elo(log_strength: np.ndarray, anchor: int | None) -> np.ndarray:
    """Elo ratings of log-strengths (last axis: systems), the anchor (or the mean) at 1000."""
    origin = log_strength[..., [anchor]] if anchor is not None else log_strength.mean(axis=-1, keepdims=True)
    return ELO_BASE + ELO_PER_LOG_ODDS * (log_strength - origin)


def leaderboard(kept: pd.DataFrame, anchor: str | None = None, model: str = BRADLEY_TERRY,
                resamples: int = RESAMPLES, seed: int = 0, confidence: float = 0.95,
                natural: str = "NAT", groupby: Sequence[str] = CELL) -> tuple[pd.DataFrame, list[str]]:
    """The leaderboard of every cell of a pairwise table's kept rows.

    ``anchor`` names the system at Elo 1000 (default ``natural`` where it was compared,
    else the systems' mean). Columns: *groupby, rank (1 = best; equal Elo, equal rank),
    system, elo, ci_low, ci_high (bootstrap percentiles), pages (shown), wins, losses,
    ties (pages won, lost, without preference), model, anchor, origin (the Elo the anchor,
    or the mean, sits at), tie_parameter (Davidson's nu, NaN otherwise), resamples,
    resamples_used, participants (whose votes were fitted) and warning (why a cell of
    too few participants has no intervals, or, for intervals from fewer than
    INTERVAL_WARNING_PARTICIPANTS, that they are less certain than they look: the one
    flag of few participants that every interval table of the report carries,
    `analysis.stats.minimums`; a note says so too). Cells without a fit are left out;
    the notes say why.
    """
    if anchor is not None and anchor not in set(kept["system"]):
        raise AnalysisInputError(f"anchor system {anchor!r} is not among the compared systems: "
                                 f"{', '.join(sorted(set(kept['system'])))}")
    tail = (1 - confidence) / 2 * 100
    rows, notes = [], []
    for key, frame in iter_cells(vote_pages(kept, groupby), groupby):
        where = " · ".join(map(str, key.values())) or "all pages"
        votes = pair_votes(frame)
        warning = too_few_for_bootstrap(len(votes.won))
        try:
            with one_blas_thread():
                fit = fit_votes(votes, model, 0 if warning else resamples, seed)
        except AnalysisInputError as exc:
            notes.append(f"No leaderboard for {where}: {exc}.")
            continue
        chosen = anchor if anchor is not None else natural if natural in votes.systems else None
        if anchor is not None and anchor not in votes.systems:
            notes.append(f"{anchor} was not compared in {where}: its leaderboard is centred on the mean.")
            chosen = None
        position = votes.systems.index(chosen) if chosen is not None else None
        scores = elo(fit.log_strength, position)
        low, high = (np.percentile(elo(fit.resampled, position), [tail, 100 - tail], axis=0)
                     if len(fit.resampled) else (np.full(len(scores), np.nan),) * 2)
        if warning:
            notes.append(f"No intervals on the leaderboard for {where}: {warning}.")
        elif len(fit.resampled) < resamples:
            notes.append(f"Leaderboard for {where}: {resamples - len(fit.resampled)} of {resamples} "
                         "bootstrap resamples had a system that never lost or never won and were "
                         "left out of the intervals.")
        participants = len(votes.won)
        if participants < INTERVAL_WARNING_PARTICIPANTS and resamples:
            notes.append(f"Leaderboard for {where}: its intervals come from {participants} participants, fewer "
                         f"than {INTERVAL_WARNING_PARTICIPANTS}; a bootstrap over so few understates the "
                         "uncertainty, so read them as rough (warning in the table).")
        rows.append(pd.DataFrame({**key, "system": votes.systems, "elo": scores, "ci_low": low,
                                  "ci_high": high, **_page_counts(frame, votes.systems),
                                  "model": model, "anchor": chosen or "mean", "origin": ELO_BASE,
                                  "tie_parameter": fit.tie_parameter, "resamples": resamples,
                                  "resamples_used": len(fit.resampled), "participants": participants,
                                  "warning": warning or few_participants_warning(participants)}))
    columns = [*groupby, "rank", "system", "elo", "ci_low", "ci_high", "pages", "wins", "losses",
               "ties", "model", "anchor", "origin", "tie_parameter", "resamples", "resamples_used",
               "participants", "warning"]
    if not rows:
        return pd.DataFrame(columns=columns), notes
    table = pd.concat(rows, ignore_index=True).sort_values([*groupby, "elo"], ascending=[True] * len(groupby) + [False])
    table["rank"] = (table.groupby(list(groupby))["elo"].rank(method="min", ascending=False)
                     if groupby else table["elo"].rank(method="min", ascending=False)).astype(int)
    return table[columns].reset_index(drop=True), notes


def _page_counts(pages: pd.DataFrame, systems: list[str]) -> dict[str, np.ndarray]:
    shown = pd.concat([pages["system_left"], pages["system_right"]]).value_counts()
    won = pages.loc[pages["winner"] != "", "winner"].value_counts()
    lost = pages.loc[pages["loser"] != "", "loser"].value_counts()
    tie = pages["answer"] == NO_PREFERENCE
    tied = pd.concat([pages.loc[tie, "system_left"], pages.loc[tie, "system_right"]]).value_counts()
    return {name: counts.reindex(systems, fill_value=0).to_numpy(dtype=int)
            for name, counts in (("pages", shown), ("wins", won), ("losses", lost), ("ties", tied))}


def battles(kept: pd.DataFrame, groupby: Sequence[str] = CELL) -> pd.DataFrame:
    """Per cell and ordered pair of systems (each pair both ways): battles (pages showing
    both), wins (of ``system`` over ``opponent``), ties, and win_fraction (wins among the
    pages with a preference; NaN without one): the heat maps' numbers."""
    pages = preference_pages(kept, groupby)
    tie = pages["answer"] == NO_PREFERENCE
    both_ways = pd.concat([
        pages.assign(system=pages["system_left"], opponent=pages["system_right"]),
        pages.assign(system=pages["system_right"], opponent=pages["system_left"])])
    both_ways["won"] = both_ways["winner"] == both_ways["system"]
    both_ways["tie"] = pd.concat([tie, tie]).to_numpy()
    table = (both_ways.groupby([*groupby, "system", "opponent"], sort=True)
             .agg(battles=("answer", "size"), wins=("won", "sum"), ties=("tie", "sum"))
             .reset_index())
    decided = table["battles"] - table["ties"]
    table["win_fraction"] = (table["wins"] / decided.where(decided > 0)).astype("float64")
    return table
