"""Adaptive pairing: the criterion against brute-force computations (and its misorders
against a simulated Gaussian model), sides balanced,
exploration, refusals, and a small seeded simulation (the full one is in the README)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq
from scipy.stats import multivariate_normal, norm

from analysis.errors import AnalysisInputError
from analysis.rankings.pairing import (PRIOR_TIES, PairingState, choose_pair, current_fit, expected_misorders,
                              expected_standard_errors, next_pair, page_effect, pair_incidence, pair_scores,
                              pairing_state, plan_pages, plan_pairs)
from analysis.reports.pairing_simulation import (Scenario, best_allocation_saving, best_joint_allocation_saving,
                                         compare_pairings, pairing_summary, simulate_votes, votes_saved)

SYSTEMS = ["NAT", "A", "B", "C", "D"]


def some_votes() -> pd.DataFrame:
    return pd.DataFrame({
        "system_left": ["NAT", "A", "B", "C", "A", "D", "NAT", "B"],
        "system_right": ["A", "B", "C", "D", "NAT", "B", "D", "A"],
        "answer": ["left", "none", "left", "right", "right", "left", "left", "right"],
        "strength": [2, pd.NA, 1, 2, 1, pd.NA, 2, 1]})


def test_the_votes_are_counted_with_the_leaderboard_weights():
    state = pairing_state(some_votes(), SYSTEMS)
    i = {s: n for n, s in enumerate(SYSTEMS)}
    assert state.wins[i["NAT"], i["A"]] == 4 + 2  # clear, then slight (A left, answered right)
    assert state.wins[i["A"], i["B"]] == 1 + 2 and state.wins[i["B"], i["A"]] == 1  # tie, then slight
    assert state.wins[i["D"], i["B"]] == 4  # a plain answer counts as clear
    assert state.shown[i["A"], i["B"]] == state.shown[i["B"], i["A"]] == 2
    assert state.left[i["A"], i["B"]] == 1 and state.left[i["B"], i["A"]] == 1


def brute_force_covariance(b: np.ndarray, pages: np.ndarray, anchor: int | None) -> np.ndarray:
    """The covariance of the log-strengths (anchor's row and column zero, or centred) of
    ``pages`` plain comparisons per pair (``np.triu_indices`` order), summed page by page."""
    k = len(b)
    information = np.zeros((k, k))
    for i, j, n in zip(*np.triu_indices(k, 1), pages):
        p = 1 / (1 + np.exp(b[j] - b[i]))
        a = np.zeros(k)
        a[i], a[j] = 1, -1
        information += n * p * (1 - p) * np.outer(a, a)
    if anchor is None:
        return np.linalg.pinv(information)
    kept = np.delete(np.arange(k), anchor)
    covariance = np.zeros((k, k))
    covariance[np.ix_(kept, kept)] = np.linalg.inv(information[np.ix_(kept, kept)])
    return covariance


def difference_variances(covariance: np.ndarray) -> np.ndarray:
    """The variance of each pair's difference (``np.triu_indices`` order)."""
    i, j = np.triu_indices(len(covariance), 1)
    return covariance[i, i] + covariance[j, j] - 2 * covariance[i, j]


def misorder_chance(mean: float, now: float, after: float) -> float:
    """P(sign of the next fit's difference != sign of the true one), the true difference
    ~ N(mean, now) and the next fit's ~ N(mean, now - after) with that covariance: two
    quadrants of scipy's bivariate normal."""
    settled = now - after
    joint = multivariate_normal([mean, mean], [[settled, settled], [settled, now]])
    both_below = joint.cdf([0.0, 0.0])
    return float(norm.cdf(-mean / np.sqrt(settled)) + norm.cdf(-mean / np.sqrt(now)) - 2 * both_below)


@pytest.mark.parametrize("anchor", [0, None])
def test_the_criterion_equals_a_brute_force_update_of_the_information(anchor):
    state = pairing_state(some_votes(), SYSTEMS)
    b = current_fit(state)
    first, second = np.triu_indices(len(SYSTEMS), 1)
    shown = state.shown[first, second] + PRIOR_TIES
    errors, misorders = [], []
    now = difference_variances(brute_force_covariance(b, shown, anchor))
    for c in range(len(first)):
        after = brute_force_covariance(b, shown + np.eye(len(first))[c], anchor)
        errors.append(np.sqrt(np.diag(after)).sum())
        misorders.append(sum(misorder_chance(b[i] - b[j], *variances)
                             for i, j, *variances in zip(first, second, now, difference_variances(after))))
    np.testing.assert_allclose(expected_standard_errors(state, b, anchor), errors, rtol=1e-10)
    np.testing.assert_allclose(expected_misorders(state, b), misorders, rtol=1e-5)
    scores = pair_scores(state, b, anchor)
    np.testing.assert_allclose(scores, np.log(errors) + np.log(misorders), rtol=1e-5)
    left, right = choose_pair(state, np.random.default_rng(0), exploration=0.0, anchor=anchor, log_strength=b)
    assert {left, right} == {first[np.argmin(scores)], second[np.argmin(scores)]}


def test_the_expected_misorders_are_the_chance_that_the_next_fit_orders_a_pair_wrongly():
    # A Gaussian model of the log-strengths: the truth drawn from the current fit and its
    # covariance, one more page of pair c an observation of its difference with variance
    # 1 / w_c, and the next fit the posterior mean; count the pairs it orders wrongly.
    state = pairing_state(some_votes(), SYSTEMS)
    b = current_fit(state)
    effect = page_effect(state, b, 0)
    rng = np.random.default_rng(5)
    c, draws = 3, 400_000
    first, second, incidence = pair_incidence(len(SYSTEMS))
    incidence = incidence[:, 1:]
    truth = b[1:] + rng.standard_normal((draws, len(SYSTEMS) - 1)) @ np.linalg.cholesky(effect.covariance).T
    w = effect.page_information[c]
    seen = truth @ incidence[c] + rng.standard_normal(draws) / np.sqrt(w)
    gain = effect.covariance @ incidence[c] / (effect.variance[c] + 1 / w)
    fitted = b[1:] + np.outer(seen - incidence[c] @ b[1:], gain)
    wrong = (np.sign(fitted @ incidence.T) != np.sign(truth @ incidence.T)).sum(axis=1)
    assert expected_misorders(state, b, effect)[c] == pytest.approx(wrong.mean(), abs=4 * wrong.std() / np.sqrt(draws))


def test_a_page_of_a_pair_that_looks_level_settles_misorders_a_page_of_a_settled_pair_does_not():
    # NAT and A fitted level after three ties (the plug-in Phi(-|m| / s') would stay at 1/2
    # for them whatever is shown), B far above C after forty clear votes
    state = PairingState.empty(["NAT", "A", "B", "C"])
    for _ in range(3):
        state.add(0, 1, "none", 1.0)
    for _ in range(40):
        state.add(2, 3, "left", 4.0)
    b = current_fit(state)
    effect = page_effect(state, b, 0)
    first, second = np.triu_indices(4, 1)
    expected_now = norm.sf(np.abs(b[first] - b[second]) / np.sqrt(effect.variance)).sum()
    misorders = expected_misorders(state, b, effect)
    level, settled = 0, len(first) - 1  # pairs NAT-A and B-C
    assert expected_now - misorders[level] > 0.1
    assert misorders[settled] == pytest.approx(expected_now, abs=1e-3)
    assert np.argmin(misorders) == level


def test_every_pair_is_balanced_in_sides_within_one_page():
    rng = np.random.default_rng(3)
    votes = pd.DataFrame(columns=["system_left", "system_right", "answer", "strength"])
    for _ in range(120):
        left, right = next_pair(votes, SYSTEMS, rng)
        answer = "left" if rng.random() < 0.5 else "right"
        votes.loc[len(votes)] = [left, right, answer, 2]
    counts = pd.crosstab(votes["system_left"], votes["system_right"]).reindex(
        index=SYSTEMS, columns=SYSTEMS, fill_value=0)
    assert np.abs(counts - counts.T).to_numpy().max() <= 1


def test_pages_planned_together_are_each_the_criterion_s_choice_given_those_before_and_keep_to_capacity():
    votes, held = some_votes(), pd.DataFrame({"system_left": ["C"], "system_right": ["NAT"]})
    capacity = {frozenset(pair): 2 for pair in [("NAT", "A"), ("A", "B"), ("C", "D"), ("NAT", "C")]}
    planned = plan_pairs(votes, SYSTEMS, 20, np.random.default_rng(4), exploration=0.0, held=held, capacity=capacity)
    assert len(planned) == 8 and all(n == 2 for n in pd.Series(map(frozenset, planned)).value_counts())
    state = pairing_state(votes, SYSTEMS)
    i = {s: n for n, s in enumerate(SYSTEMS)}
    state.hand_out(i["C"], i["NAT"])
    b = current_fit(state)
    first, second = np.triu_indices(len(SYSTEMS), 1)
    room = {frozenset((SYSTEMS[a], SYSTEMS[c])): 2 for a, c in zip(first, second)
            if frozenset((SYSTEMS[a], SYSTEMS[c])) in capacity}
    for left, right in planned:  # the fit stays; each page planned adds its information for the next
        open_pairs = [c for c, (a, d) in enumerate(zip(first, second)) if room.get(frozenset((SYSTEMS[a], SYSTEMS[d])))]
        scores = pair_scores(state, b, i["NAT"])
        best = min(scores[c] for c in open_pairs)
        assert scores[[c for c, (a, d) in enumerate(zip(first, second))
                       if {a, d} == {i[left], i[right]}][0]] <= best + 1e-12 * max(1.0, abs(best))
        room[frozenset((left, right))] -= 1
        state.hand_out(i[left], i[right])
    assert plan_pairs(votes, SYSTEMS, 1, np.random.default_rng(9)) == [next_pair(votes, SYSTEMS, np.random.default_rng(9))]


def test_full_exploration_draws_every_pair_uniformly():
    state = pairing_state(some_votes(), SYSTEMS)
    rng = np.random.default_rng(1)
    drawn = pd.Series([frozenset(choose_pair(state, rng, exploration=1.0)) for _ in range(2000)]).value_counts()
    assert len(drawn) == 10 and drawn.min() > 150 and drawn.max() < 250  # 200 expected each


def test_the_first_pair_needs_no_votes_and_the_anchor_may_be_absent():
    empty = pd.DataFrame(columns=["system_left", "system_right", "answer"])
    left, right = next_pair(empty, SYSTEMS, np.random.default_rng(0))
    assert left != right and {left, right} <= set(SYSTEMS)
    left, right = next_pair(some_votes(), SYSTEMS, np.random.default_rng(0), anchor="absent")
    assert left != right


def test_votes_of_unknown_systems_or_without_columns_are_refused():
    with pytest.raises(AnalysisInputError, match="name system.s. E that are not among the systems"):
        next_pair(some_votes().replace({"D": "E"}), SYSTEMS, np.random.default_rng(0))
    with pytest.raises(AnalysisInputError, match="lack the column.s. answer"):
        next_pair(some_votes().drop(columns="answer"), SYSTEMS, np.random.default_rng(0))
    with pytest.raises(AnalysisInputError, match="exploration must lie in"):
        choose_pair(PairingState.empty(SYSTEMS), np.random.default_rng(0), exploration=1.5)
    with pytest.raises(AnalysisInputError, match="exploration must lie in"):  # even when no page is asked for
        plan_pairs(some_votes(), SYSTEMS, 0, np.random.default_rng(0), exploration=5)
    with pytest.raises(AnalysisInputError, match="pairing needs at least two systems"):
        next_pair(some_votes().iloc[:0], ["A"], np.random.default_rng(0))


def test_the_best_allocation_for_three_equal_systems_saves_two_minus_root_three_quarters():
    # anchored at the first: pages a, a, 1 - 2a on 0-1, 0-2, 1-2; the best a = 1 - 1/sqrt(3)
    equal = Scenario({"A": 1000.0, "B": 1000.0, "C": 1000.0})
    assert best_allocation_saving(equal) == pytest.approx((2 - np.sqrt(3)) / 4, abs=1e-5)
    assert best_joint_allocation_saving(equal, 300) == best_allocation_saving(equal)  # no order to get wrong


def test_votes_saved_interpolates_between_checkpoints():
    summary = pd.DataFrame({
        "pairing": ["uniform"] * 2 + ["adaptive"] * 2, "votes": [100, 200] * 2,
        "kendall_tau": [0.8, 0.9, 0.85, 0.95], "mean_width": [200.0, 150.0, 180.0, 120.0]})
    saved = votes_saved(summary).set_index("uniform_votes")
    assert saved.loc[100, "at_least"] and saved.loc[100, "saving"] == 0.0
    # tau 0.9 at 100 + (0.9 - 0.85) / 0.1 * 100 = 150 votes; width 150 at 100 + 30/60 * 100 = 150
    assert saved.loc[200, ["adaptive_votes_for_tau", "adaptive_votes_for_width"]].tolist() == pytest.approx([150, 150])
    assert saved.loc[200, "saving"] == pytest.approx(0.25) and not saved.loc[200, "at_least"]


def test_no_saving_is_claimed_where_either_measure_is_not_reached():
    def saved_at_200(adaptive_tau: list[float], adaptive_width: list[float]) -> pd.Series:
        summary = pd.DataFrame({"pairing": ["uniform"] * 2 + ["adaptive"] * 2, "votes": [100, 200] * 2,
                                "kendall_tau": [0.8, 0.9, *adaptive_tau],
                                "mean_width": [200.0, 150.0, *adaptive_width]})
        return votes_saved(summary).set_index("uniform_votes").loc[200]

    width_missed = saved_at_200([0.95, 0.97], [210.0, 160.0])  # tau 0.9 reached at 100 votes, width 150 never
    assert width_missed["adaptive_votes_for_tau"] == 100 and np.isnan(width_missed["adaptive_votes_for_width"])
    assert np.isnan(width_missed["adaptive_votes"]) and np.isnan(width_missed["saving"])
    tau_missed = saved_at_200([0.7, 0.85], [100.0, 90.0])
    assert np.isnan(tau_missed["adaptive_votes_for_tau"]) and tau_missed["adaptive_votes_for_width"] == 100
    assert np.isnan(tau_missed["adaptive_votes"]) and np.isnan(tau_missed["saving"])


def test_a_small_seeded_simulation_is_reproducible_and_adaptive_pairing_narrows_the_intervals():
    scenario = Scenario({"NAT": 1000.0, "A": 800.0, "B": 600.0, "C": 400.0, "D": 200.0}, resamples=200)
    results = compare_pairings(scenario, studies=8, checkpoints=(600,), seed=4)
    pd.testing.assert_frame_equal(results.iloc[:1], compare_pairings(scenario, 1, (600,), seed=4).iloc[:1])
    summary = pairing_summary(results).set_index(["pairing", "votes"])
    assert summary.loc[("adaptive", 600), "mean_width"] < summary.loc[("uniform", 600), "mean_width"]
    pages = simulate_votes(scenario, "adaptive", 600, seed=1)
    shown = pd.crosstab(pages["system_left"], pages["system_right"])
    shown = (shown + shown.T).stack()
    assert shown[("NAT", "D")] < 600 / 10  # a foregone pair gets fewer pages than uniform's share


def test_a_simulated_participant_s_pages_are_planned_at_once_as_a_study_plans_them():
    scenario = Scenario({"NAT": 1000.0, "A": 800.0, "B": 790.0, "C": 400.0}, pages_per_participant=6)
    pages = simulate_votes(scenario, "adaptive", 12, seed=2)
    index = {s: i for i, s in enumerate(scenario.systems)}
    shown = list(zip(pages["system_left"].map(index), pages["system_right"].map(index)))
    state = PairingState.empty(scenario.systems)
    assert plan_pages(state, 6, np.random.default_rng(2), anchor=0) == shown[:6]  # from the prior alone
    assert state.shown.sum() == 2 * 6 and not state.wins.any()  # handed out, not answered


def test_the_joint_ceiling_is_the_best_allocation_of_a_grid_and_below_the_width_ceiling():
    # three systems: every allocation is (a, c, 1 - a - c) on pairs 0-1, 0-2, 1-2
    scenario = Scenario({"A": 1000.0, "B": 960.0, "C": 800.0})
    votes = 300
    ceiling = best_joint_allocation_saving(scenario, votes)
    first, second = np.triu_indices(3, 1)
    b = scenario.log_strength
    gap = np.abs(b[first] - b[second])

    def measures(share: np.ndarray, n: float) -> tuple[float, float]:
        covariance = brute_force_covariance(b, n * share, anchor=0)
        sd = np.sqrt(difference_variances(covariance))
        return float(np.sqrt(np.diag(covariance)).sum()), float(norm.sf(gap / sd).sum())

    target = measures(np.full(3, 1 / 3), votes)
    grid = np.linspace(0.02, 0.96, 32)
    best_ratio = np.inf
    for a in grid:
        for c in grid[grid < 1 - a - 0.01]:
            share = np.array([a, c, 1 - a - c])
            ratio = max(brentq(lambda n, m=m: measures(share, n)[m] - target[m], 1, 1e6) for m in (0, 1)) / votes
            best_ratio = min(best_ratio, ratio)
    assert 1 - ceiling == pytest.approx(best_ratio, abs=0.01)
    assert ceiling <= best_allocation_saving(scenario) + 1e-6
