"""How many more ratings: each design's closed form against a simulation of its own test.

At the computed number of ratings, data drawn with the observed effect and analysed with
the design's actual test (Welch t for single, scipy.stats.wilcoxon for side-by-side,
scipy.stats.binomtest for pairwise) must reach the target power.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from analysis.ratings.exclusions import apply_exclusions
from analysis.stats.power import (SEQUENTIAL_LOOKS_NOTE, pages_for_page_effect, pages_for_preference, power_summary,
                                  ratings_per_system_for_effect, sign_test_power, sign_test_trials_for_power,
                                  walsh_positive_share)
from analysis.ratings.more_ratings import more_ratings_for_power
from analysis.ratings.schema import validate_ratings
from analysis.ratings.simulate import simulate_pairwise, simulate_ratings, simulate_side_by_side

pytestmark = pytest.mark.slow

ALPHA_PAIR = 0.05 / 3  # three systems: three pairs, Bonferroni


def kept_of(table: pd.DataFrame) -> pd.DataFrame:
    flagged = apply_exclusions(validate_ratings(table.astype(str)))
    return flagged[flagged["kept"] & (flagged["system"] != "BAD")]


def test_single_design_sample_size_reaches_the_power_with_welch_t_tests():
    kept = kept_of(simulate_ratings({"NAT": 4.1, "A": 3.4, "B": 3.2}, 2400, control_classes=("c",),
                                    inattentive_share=0.0, seed=3))
    power = more_ratings_for_power(kept).set_index(["system_a", "system_b"])
    a_b = power.loc[("A", "B")]
    assert a_b["unit"] == "ratings per system" and a_b["alpha_pair"] == pytest.approx(ALPHA_PAIR)
    values = {s: kept.loc[kept["system"] == s, "value"].to_numpy() for s in ("A", "B")}
    assert a_b["effect"] == pytest.approx(values["A"].mean() - values["B"].mean())
    n = int(a_b["n_needed"])
    rng = np.random.default_rng(0)
    # resampling the observed ratings keeps their (discrete, skewed) distribution
    x = rng.choice(values["A"], (2000, n))
    y = rng.choice(values["B"], (2000, n))
    achieved = (stats.ttest_ind(x, y, axis=1, equal_var=False).pvalue < ALPHA_PAIR).mean()
    assert 0.76 <= achieved <= 0.84
    assert a_b["n_more"] == max(0, n - a_b["n_now"])
    assert power.loc[("A", "NAT"), "n_more"] == 0 and power.loc[("A", "NAT"), "power_now"] > 0.99


def test_side_by_side_sample_size_reaches_the_power_with_scipy_wilcoxon():
    kept = kept_of(simulate_side_by_side({"NAT": 75, "A": 60, "B": 56}, n_participants=12,
                                         inattentive_share=0.0, seed=8))
    power = more_ratings_for_power(kept).set_index(["system_a", "system_b"])
    a_b = power.loc[("A", "B")]
    wide = kept.pivot_table(index=["participant", "page"], columns="system", values="value")
    d = (wide["A"] - wide["B"]).dropna().to_numpy()
    per_participant = len(d) / kept["participant"].nunique()
    assert a_b["unit"] == "pages" and a_b["n_now"] == len(d)
    assert a_b["per_participant"] == pytest.approx(per_participant)
    n = int(a_b["n_needed"])
    sims = np.random.default_rng(1).choice(d, (2000, n))
    achieved = (stats.wilcoxon(sims, axis=1, method="asymptotic").pvalue < ALPHA_PAIR).mean()
    # Noether's formula is a large-sample approximation, on the safe side for small n
    assert 0.76 <= achieved <= 0.9
    assert a_b["participants_more"] == np.ceil(a_b["n_more"] / per_participant)


def test_walsh_share_counts_pair_sums_like_brute_force():
    d = np.array([-3.0, -1.0, 1.0, 1.0, 2.0, 5.0, -2.0])
    i, j = np.triu_indices(len(d), 1)
    sums = d[i] + d[j]
    assert walsh_positive_share(d) == pytest.approx(((sums > 0) + 0.5 * (sums == 0)).mean())


def test_sign_test_power_equals_the_binomtest_rejection_region():
    for n, share in [(10, 0.7), (37, 0.6), (120, 0.55), (200, 0.4)]:
        k = np.arange(n + 1)
        rejects = np.array([stats.binomtest(int(x), n).pvalue <= ALPHA_PAIR for x in k])
        assert sign_test_power(n, share, ALPHA_PAIR) == pytest.approx(
            stats.binom.pmf(k[rejects], n, share).sum(), rel=1e-10)


def test_pairwise_sample_size_is_the_first_n_that_stays_above_the_power():
    n = int(sign_test_trials_for_power(0.65, ALPHA_PAIR, 0.8))
    powers = sign_test_power(np.arange(1, n + 300), 0.65, ALPHA_PAIR)
    assert powers[n - 2] < 0.8 and (powers[n - 1:] >= 0.8).all()
    assert np.isnan(sign_test_trials_for_power(0.5, ALPHA_PAIR, 0.8))


def test_pairwise_pages_needed_allow_for_no_preference_answers():
    kept = kept_of(simulate_pairwise({"NAT": 1.0, "A": 0.3, "B": 0.15}, n_participants=20,
                                     no_preference_share=0.25, inattentive_share=0.0, seed=2))
    power = more_ratings_for_power(kept).set_index(["system_a", "system_b"])
    a_b = power.loc[("A", "B")]
    pages = kept[kept["system"] == "A"].merge(kept[kept["system"] == "B"], on=["participant", "page"])
    decided = pages[pages["answer_x"] != "none"]
    share = ((decided["answer_x"] == decided["side_x"]).mean())
    assert a_b["effect"] == pytest.approx(share - 0.5)
    trials = sign_test_trials_for_power(share, ALPHA_PAIR, 0.8)
    assert a_b["n_needed"] == np.ceil(trials / (len(decided) / len(pages)))
    rng = np.random.default_rng(3)
    wins = rng.binomial(int(trials), share, 4000)
    rejects = np.array([stats.binomtest(k, int(trials)).pvalue <= ALPHA_PAIR for k in range(int(trials) + 1)])
    achieved = rejects[wins].mean()
    assert achieved >= 0.78


def test_a_pair_without_any_difference_needs_no_number_and_says_so():
    rows = [{"task": "t", "control_class": "c", "participant": f"p{i}", "system": s, "value": v}
            for i in range(6) for s, v in (("A", 2 + i % 3), ("B", 2 + i % 3))]
    power = more_ratings_for_power(pd.DataFrame(rows)).iloc[0]
    assert np.isnan(power["n_needed"]) and np.isnan(power["n_more"])
    text = power_summary(more_ratings_for_power(pd.DataFrame(rows)))
    assert "1 pair(s) show no difference, or too few answers" in text and SEQUENTIAL_LOOKS_NOTE in text


def test_the_participants_needed_bring_the_pages_needed_under_random_pairing():
    systems = {"NAT": 1.0, "A": 0.5, "B": 0.0, "C": -0.4, "D": -0.8, "E": -1.2}  # 15 pairs
    options = dict(pages_per_participant=10, no_preference_share=0.0, inattentive_share=0.0, early_share=0.0)
    rate = 10 / 15  # pages of a given pair a new participant brings under random pairing
    rows = []
    for seed in range(40):
        power = more_ratings_for_power(kept_of(simulate_pairwise(systems, n_participants=30, seed=seed, **options)))
        rows.append(power.set_index(["system_a", "system_b"]).loc[("A", "B")])
    table = pd.DataFrame(rows)
    # the rate counts every participant, not only those who happened to see the pair (about
    # half of them, which doubled it); 40 studies estimate it within about 3.5 % (one se)
    assert table["per_participant"].mean() == pytest.approx(rate, rel=0.1)
    # so the participants asked for bring the pages needed (a little more: 1 / rate is convex)
    brought = (table["participants_more"] * rate / table["n_more"]).mean()
    assert 0.9 <= brought <= 1.25


# Planning from an expected effect (the study app's plan, locked when a study opens).


@pytest.mark.parametrize("d, pairs", [(0.5, 3), (0.3, 1), (0.8, 6)])
def test_planned_ratings_per_system_match_statsmodels_normal_power(d, pairs):
    from statsmodels.stats.power import NormalIndPower
    expected = NormalIndPower().solve_power(effect_size=d, alpha=0.05 / pairs, power=0.8, ratio=1)
    assert ratings_per_system_for_effect(d, pairs) == int(np.ceil(expected))


def test_planned_preference_pages_are_the_first_with_the_exact_sign_tests_power():
    share, pairs = 0.65, 3
    n = pages_for_preference(share, pairs)

    def exact_power(trials: int) -> float:  # every outcome the two-sided binomial test rejects, by scipy
        return sum(stats.binom.pmf(k, trials, share) for k in range(trials + 1)
                   if stats.binomtest(k, trials, 0.5).pvalue <= 0.05 / pairs)

    assert exact_power(n) >= 0.8 > exact_power(n - 1)
    assert all(exact_power(m) >= 0.8 for m in range(n, n + 15))  # it saw-tooths, but no longer below


def test_planned_side_by_side_pages_give_the_wilcoxon_test_its_power_in_simulation():
    d, pairs = 0.4, 3
    n = pages_for_page_effect(d, pairs)
    rng = np.random.default_rng(7)
    rejected = [stats.wilcoxon(rng.normal(d, 1, n)).pvalue <= 0.05 / pairs for _ in range(600)]
    assert abs(np.mean(rejected) - 0.8) < 0.06


@pytest.mark.parametrize("plan, effect, words", [(ratings_per_system_for_effect, 0.0, "above 0"),
                                                  (pages_for_page_effect, float("nan"), "above 0"),
                                                  (pages_for_preference, 0.5, "above 0.5 and at most 1"),
                                                  (pages_for_preference, 1.2, "above 0.5 and at most 1")])
def test_an_effect_no_test_can_plan_for_is_refused_by_name(plan, effect, words):
    with pytest.raises(ValueError, match=f"expected effect.*must lie {words}"):
        plan(effect, 3)
