"""Does adaptive pairing save votes? A seeded simulation of pairwise studies.

A scenario is the systems' true Elo (the first is the leaderboard's anchor, as NAT is).
Each simulated study collects votes one page at a time, ``pages_per_participant`` pages
per participant, participant after participant, the pair of each page chosen

- ``uniform``: every pair equally likely, sides at random;
- ``adaptive``: as a study with adaptive pairing plans them: a participant's pages at
  once, when they start, by `analysis.rankings.pairing.plan_pages` from one fit of the votes so
  far (its default exploration, sides balanced per pair, the first system as the
  anchor; participants one after another, so none holds pages unanswered meanwhile);

and answered on five levels by `analysis.rankings.graded_votes` (drawn so that the weighted
Bradley-Terry model holds in expectation whatever the pairs shown, so the true Elo is
what the leaderboard estimates under either pairing).

At each checkpoint (a number of votes) the study's leaderboard (`analysis.rankings.leaderboard`:
weighted Bradley-Terry, bootstrap over participants) gives Kendall's tau between the
estimated and the true order, the mean width of the 95 % intervals of the systems other
than the anchor, and whether each of those intervals covers the true Elo.

`votes_saved` reads the summary per pairing and checkpoint: for each uniform checkpoint,
the votes at which the adaptive pairing reaches the same mean tau and the same mean
width (interpolated linearly between its checkpoints; the larger of the two), and the
share of votes saved. `best_allocation_saving` is the ceiling for the widths: the saving
of the best fixed allocation of pages over pairs for the true strengths (minimising the
sum of standard errors), which no pairing can beat asymptotically.
`best_joint_allocation_saving` is the ceiling for both at once: the best fixed
allocation that matches uniform pairing's summed standard errors and its expected number
of misordered pairs (the normal approximation of Kendall's tau) with fewest votes.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import optimize
from scipy import stats as sps

from analysis.reports import plots
from analysis.blas import one_blas_thread
from analysis.errors import AnalysisInputError
from analysis.rankings.graded_votes import draw_levels, level_answers
from analysis.rankings.leaderboard import (ELO_PER_LOG_ODDS, TIE_WEIGHT, WINS_PER_DEGREE, elo, fit_votes,
                                  pair_votes, vote_weights)
from analysis.reports.leaderboard_plots import pairing_plot
from analysis.rankings.pairing import (EXPLORATION, PairingState, comparison_information, current_fit, pair_incidence,
                              plan_pages)
from analysis.reports.tables import write_table

UNIFORM, ADAPTIVE = "uniform", "adaptive"
PAIRINGS = (UNIFORM, ADAPTIVE)
# NAT on top, one system close to it, a cluster of similar ones, weaker baselines far below
DEFAULT_ELO = {"NAT": 1000.0, "S1": 940.0, "S2": 880.0, "S3": 860.0, "S4": 760.0,
               "S5": 740.0, "S6": 720.0, "S7": 560.0, "S8": 480.0, "S9": 300.0}
DEFAULT_VOTES = (500, 1000, 1500, 2000, 2500, 3000)
_ANSWERS = {1: "left", -1: "right", 0: "none"}


@dataclass(frozen=True)
class Scenario:
    """What every simulated study shares."""

    elo: Mapping[str, float]
    pages_per_participant: int = 20
    exploration: float = EXPLORATION
    tie_peak: float = 0.25
    resamples: int = 1000
    confidence: float = 0.95

    @property
    def systems(self) -> list[str]:
        return list(self.elo)

    @property
    def log_strength(self) -> np.ndarray:
        values = np.array(list(self.elo.values()), dtype=np.float64)
        return (values - values[0]) / ELO_PER_LOG_ODDS


def simulate_votes(scenario: Scenario, pairing: str, votes: int, seed: int) -> pd.DataFrame:
    """One study's pages in order: participant, system_left, system_right, answer,
    strength, weight."""
    if pairing not in PAIRINGS:
        raise AnalysisInputError(f"pairing must be one of {', '.join(PAIRINGS)}; got {pairing!r}")
    rng = np.random.default_rng(seed)
    truth = scenario.log_strength
    k = len(truth)
    if pairing == UNIFORM:
        first, second = np.triu_indices(k, 1)
        pair = rng.integers(len(first), size=votes)
        swap = rng.random(votes) < 0.5
        left, right = np.where(swap, second[pair], first[pair]), np.where(swap, first[pair], second[pair])
        levels = draw_levels(rng, truth[left] - truth[right], scenario.tie_peak)
    else:
        left, right, levels = np.zeros(votes, int), np.zeros(votes, int), np.zeros(votes, int)
        state = PairingState.empty(scenario.systems)
        fit = np.zeros(k)
        for start in range(0, votes, scenario.pages_per_participant):  # one participant at a time
            fit = current_fit(state, fit)
            pages = min(scenario.pages_per_participant, votes - start)
            planned = plan_pages(state, pages, rng, scenario.exploration, anchor=0, log_strength=fit)
            for vote, (left[vote], right[vote]) in enumerate(planned, start):
                levels[vote] = draw_levels(rng, truth[left[vote]] - truth[right[vote]], scenario.tie_peak)
                weight = TIE_WEIGHT if levels[vote] == 0 else WINS_PER_DEGREE * abs(levels[vote])
                state.answer(left[vote], right[vote], _ANSWERS[np.sign(levels[vote])], weight)
    answer, strength = level_answers(levels)
    system = np.array(scenario.systems)
    rows = {"participant": np.char.add("p", (np.arange(votes) // scenario.pages_per_participant).astype(str)),
            "system_left": system[left], "system_right": system[right], "answer": answer, "strength": strength}
    pages = pd.DataFrame(rows)
    pages["weight"] = vote_weights(pages["answer"], pages["strength"])
    return pages


def score_study(pages: pd.DataFrame, scenario: Scenario, checkpoints: Sequence[int],
                seed: int) -> list[dict]:
    """Per checkpoint: Kendall's tau, mean interval width (Elo) and the share of the
    non-anchor systems whose interval covers the true Elo (NaN where no fit exists)."""
    truth = elo(scenario.log_strength, 0)
    tail = (1 - scenario.confidence) / 2 * 100
    rows = []
    for votes in checkpoints:
        shown = pair_votes(pages.iloc[:votes], scenario.systems)
        try:
            fit = fit_votes(shown, resamples=scenario.resamples, seed=seed)
        except AnalysisInputError:
            rows.append({"votes": votes, "kendall_tau": np.nan, "mean_width": np.nan, "covered": np.nan})
            continue
        low, high = np.percentile(elo(fit.resampled, 0), [tail, 100 - tail], axis=0)
        inside = (low <= truth) & (truth <= high)
        rows.append({"votes": votes,
                     "kendall_tau": float(sps.kendalltau(elo(fit.log_strength, 0), truth).statistic),
                     "mean_width": float((high - low)[1:].mean()), "covered": float(inside[1:].mean())})
    return rows


def _one_study(job: tuple[Scenario, str, int, Sequence[int], int]) -> list[dict]:
    scenario, pairing, study, checkpoints, seed = job
    study_seed = int(np.random.SeedSequence([seed, study, PAIRINGS.index(pairing)]).generate_state(1)[0])
    with one_blas_thread():
        pages = simulate_votes(scenario, pairing, max(checkpoints), study_seed)
        rows = score_study(pages, scenario, checkpoints, study_seed)
    return [{"pairing": pairing, "study": study, **row} for row in rows]


def compare_pairings(scenario: Scenario, studies: int, checkpoints: Sequence[int] = DEFAULT_VOTES,
                     seed: int = 0, workers: int = 1) -> pd.DataFrame:
    """Per pairing, study and checkpoint: votes, kendall_tau, mean_width, covered.
    Study s of a pairing is seeded by (seed, s, pairing), whatever ``workers`` is."""
    jobs = [(scenario, pairing, study, sorted(checkpoints), seed)
            for pairing in PAIRINGS for study in range(studies)]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            results = list(pool.map(_one_study, jobs, chunksize=1))
    else:
        results = [_one_study(job) for job in jobs]
    return pd.DataFrame([row for rows in results for row in rows])


def pairing_summary(results: pd.DataFrame) -> pd.DataFrame:
    """Per pairing and votes: studies (with a fit), and the mean over studies with its
    standard error of kendall_tau, mean_width and coverage (each study's share of
    intervals covering the truth: the intervals of one study are not independent, so the
    error is taken over studies)."""
    grouped = results.groupby(["pairing", "votes"], sort=True)
    return grouped.agg(studies=("kendall_tau", "count"),
                       kendall_tau=("kendall_tau", "mean"), tau_se=("kendall_tau", "sem"),
                       mean_width=("mean_width", "mean"), width_se=("mean_width", "sem"),
                       coverage=("covered", "mean"), coverage_se=("covered", "sem")).reset_index()


def _votes_to_reach(votes: np.ndarray, values: np.ndarray, target: float, higher_is_better: bool) -> float:
    """The votes at which ``values`` (one per checkpoint) first reach ``target``,
    interpolated linearly between checkpoints; NaN when they never do."""
    good = values >= target if higher_is_better else values <= target
    if not good.any():
        return np.nan
    i = int(np.argmax(good))
    if i == 0:
        return float(votes[0])
    v0, v1, y0, y1 = votes[i - 1], votes[i], values[i - 1], values[i]
    return float(v0 + (target - y0) / (y1 - y0) * (v1 - v0))


def votes_saved(summary: pd.DataFrame) -> pd.DataFrame:
    """Per uniform checkpoint: its mean tau and width, the adaptive votes that reach each
    (NaN beyond the adaptive checkpoints), the votes that reach both (NaN where either is
    not reached), and the saving;
    ``at_least`` where both were reached at the first checkpoint, so the adaptive pairing
    may need fewer votes still."""
    uniform = summary[summary["pairing"] == UNIFORM].sort_values("votes")
    adaptive = summary[summary["pairing"] == ADAPTIVE].sort_values("votes")
    votes = adaptive["votes"].to_numpy(np.float64)
    rows = []
    for row in uniform.itertuples(index=False):
        for_tau = _votes_to_reach(votes, adaptive["kendall_tau"].to_numpy(), row.kendall_tau, True)
        for_width = _votes_to_reach(votes, adaptive["mean_width"].to_numpy(), row.mean_width, False)
        both = np.nan if np.isnan(for_tau) or np.isnan(for_width) else max(for_tau, for_width)
        rows.append({"uniform_votes": row.votes, "uniform_tau": row.kendall_tau,
                     "uniform_width": row.mean_width, "adaptive_votes_for_tau": for_tau,
                     "adaptive_votes_for_width": for_width, "adaptive_votes": both,
                     "saving": 1 - both / row.votes, "at_least": both == votes[0]})
    return pd.DataFrame(rows)


def _allocation_measures(scenario: Scenario) -> tuple[Callable, Callable]:
    """For the true strengths, two functions of an allocation (page shares over the pairs,
    ``np.triu_indices`` order) and a number of votes: the summed standard errors of the
    systems against the anchor, and the expected number of misordered pairs of systems,
    ``sum over i < j of Phi(-|b_i - b_j| / sd(b_i - b_j))``; a page counts as one plain
    comparison (Fisher information ``p (1 - p)``)."""
    b = scenario.log_strength
    first, second, incidence = pair_incidence(len(b))
    w = comparison_information(b, first, second)
    gap = np.abs(b[first] - b[second])

    def covariance(share: np.ndarray, votes: float) -> np.ndarray:
        information = incidence.T @ ((votes * share * w)[:, None] * incidence)
        return np.linalg.inv(information[1:, 1:])

    def summed_errors(share: np.ndarray, votes: float) -> float:
        return float(np.sqrt(np.diag(covariance(share, votes))).sum())

    def misorders(share: np.ndarray, votes: float) -> float:
        rows = incidence[:, 1:]
        variance = np.einsum("dk,kl,dl->d", rows, covariance(share, votes), rows)
        return float(sps.norm.sf(gap / np.sqrt(variance)).sum())

    return summed_errors, misorders


def _shares(logits: np.ndarray) -> np.ndarray:
    share = np.exp(logits - logits.max())
    return share / share.sum()


def best_allocation_saving(scenario: Scenario) -> float:
    """The share of votes that the best fixed allocation of pages over pairs, for the true
    strengths, saves against uniform pairing at equal sums of standard errors."""
    summed_errors, _ = _allocation_measures(scenario)
    pairs = len(scenario.elo) * (len(scenario.elo) - 1) // 2
    best = optimize.minimize(lambda logits: summed_errors(_shares(logits), 1.0), np.zeros(pairs),
                             method="L-BFGS-B")
    # standard errors fall as 1 / sqrt(votes): equal sums need (best / uniform)^2 the votes
    return 1.0 - (best.fun / summed_errors(np.full(pairs, 1 / pairs), 1.0)) ** 2


def best_joint_allocation_saving(scenario: Scenario, votes: int) -> float:
    """The share of votes that the best fixed allocation, for the true strengths, saves
    against ``votes`` uniformly paired pages while matching both their summed standard
    errors and their expected misordered pairs (`_allocation_measures`): the ceiling of a
    saving in interval width and in Kendall's tau at once. Found by minimising a smooth
    maximum of the two vote ratios over the allocation's logits."""
    if not np.ptp(scenario.log_strength):  # every system level: no order to get wrong
        return best_allocation_saving(scenario)
    summed_errors, misorders = _allocation_measures(scenario)
    pairs = len(scenario.elo) * (len(scenario.elo) - 1) // 2
    uniform = np.full(pairs, 1 / pairs)
    targets = summed_errors(uniform, votes), misorders(uniform, votes)

    def ratios(share: np.ndarray) -> tuple[float, float]:
        """Votes the allocation needs for each uniform measure, over ``votes`` (at most 1,000:
        an allocation that starves a system needs more than any study has)."""
        def ratio(measure: Callable, target: float) -> float:
            if measure(share, votes * 1e3) > target:
                return 1e3
            return optimize.brentq(lambda n: measure(share, n) - target, votes * 1e-3, votes * 1e3) / votes
        return ratio(summed_errors, targets[0]), ratio(misorders, targets[1])

    sharpness = 60.0  # log-sum-exp: within log(2) / 60, about 1 % of the votes, of the maximum
    best = optimize.minimize(lambda logits: np.logaddexp(*(sharpness * np.array(ratios(_shares(logits)))))
                             / sharpness, np.zeros(pairs), method="L-BFGS-B")
    return 1.0 - max(ratios(_shares(best.x)))


def pairing_text(scenario: Scenario, summary: pd.DataFrame, saved: pd.DataFrame, ceiling: float,
                 studies: int, seed: int) -> str:
    """The simulation's setting and findings in words."""
    truth = ", ".join(f"{s} {v:g}" for s, v in scenario.elo.items())
    text = (f"{studies} simulated studies per pairing of a {len(scenario.elo)}-system pairwise "
            f"study (true Elo: {truth}; the first is the anchor), {scenario.pages_per_participant} "
            f"pages per participant, five-level answers, adaptive exploration epsilon = "
            f"{scenario.exploration:g}, seed {seed}; each scored with the leaderboard (weighted "
            f"Bradley-Terry, {scenario.resamples:,} bootstrap resamples of the participants, "
            f"{scenario.confidence * 100:g} % intervals).")
    first = summary["votes"].min()
    for row in saved.itertuples(index=False):
        text += (f" Uniform pairing at {row.uniform_votes:,} votes: mean tau {row.uniform_tau:.3f}, mean "
                 f"interval width {row.uniform_width:.0f} Elo; adaptive pairing reaches the tau "
                 f"{_votes_phrase(row.adaptive_votes_for_tau, row.uniform_votes, first)}, the width "
                 f"{_votes_phrase(row.adaptive_votes_for_width, row.uniform_votes, first)}; the best "
                 f"fixed allocation matching both would save {row.joint_ceiling * 100:.0f} %.")
    text += (f" The best fixed allocation for the true strengths would save {ceiling * 100:.0f} % "
             "of the votes at equal standard errors alone.")
    coverage = ", ".join(f"{r.pairing} at {r.votes:,} votes {r.coverage * 100:.1f} % "
                         f"(± {r.coverage_se * 100:.1f})" for r in summary.itertuples(index=False)
                         if r.votes == summary["votes"].max())
    return text + f" Coverage of the true Elo by the intervals: {coverage}."


def _votes_phrase(votes: float, uniform_votes: int, first: int) -> str:
    if np.isnan(votes):
        return "not within the simulated votes"
    if votes <= first:
        return f"by its first checkpoint ({first:,} votes)"
    change = 1 - votes / uniform_votes
    return f"at {votes:,.0f} votes ({abs(change) * 100:.0f} % {'fewer' if change >= 0 else 'more'})"


def write_pairing_simulation(scenario: Scenario, results: pd.DataFrame, folder: str | Path,
                             studies: int, seed: int) -> tuple[list[Path], str]:
    """Write tables (pairing_studies, pairing_summary, votes_saved), the figure and
    summary.md into ``folder``; return the files and the summary's text."""
    folder = Path(folder)
    summary = pairing_summary(results)
    saved = votes_saved(summary)
    saved["joint_ceiling"] = [best_joint_allocation_saving(scenario, votes) for votes in saved["uniform_votes"]]
    text = pairing_text(scenario, summary, saved, best_allocation_saving(scenario), studies, seed)
    written = write_table(results, folder / "tables", "pairing_studies", formats=("csv",))
    written += write_table(summary, folder / "tables", "pairing_summary",
                           caption="Kendall's tau, mean interval width and coverage per pairing and votes.")
    written += write_table(saved, folder / "tables", "votes_saved",
                           caption="Votes adaptive pairing needs to match uniform pairing, and the best "
                                   "fixed allocation's saving for both measures at once.")
    written += plots.save_figure(pairing_plot(summary), folder / "figures", "pairing")
    path = folder / "summary.md"
    path.write_text(f"# Adaptive against uniform pairing\n\n{text}\n", encoding="utf-8")
    return [path, *written], text
