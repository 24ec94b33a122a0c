"""Benchmark of the ranking analyses against their targets; exits non-zero when one is missed.

    .venv/bin/python benchmarks/bench_rankings.py [--json]

1. The leaderboard of 2,400 graded votes of 8 systems (120 participants x 20 pages) with
   10,000 bootstrap resamples: target "seconds" (10 s). Reference, same run: refitting
   resamples one at a time with statsmodels' GLM (binomial, frequency weights) on the
   resample's pair totals, timed on 100 resamples and scaled to 10,000.
2. The crossed linear mixed model and the cumulative link mixed model of 7,200 Likert
   ratings (150 participants, 120 clips, 3 systems), one after the other: target 10 s
   together on one core. Reference for the linear model, same run: statsmodels' MixedLM
   with the two factors as variance components.

Everything runs on one core (BLAS threads set to 1 before numpy loads); times are CPU
seconds of this process.
"""

from __future__ import annotations

import os

os.environ.update({name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})

import argparse  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import statsmodels.api as sm  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from analysis.raters.crossed_mixed import crossed_mixed_model  # noqa: E402
from analysis.rankings.graded_votes import simulate_graded_pairwise  # noqa: E402
from analysis.rankings.leaderboard import leaderboard, pair_votes, participant_resamples, vote_pages  # noqa: E402
from analysis.raters.ordinal_mixed import ordinal_mixed_model  # noqa: E402
from analysis.ratings.schema import read_ratings  # noqa: E402
from benchmarks.machine import describe_machine  # noqa: E402

LEADERBOARD_TARGET_S = 10.0
MIXED_MODELS_TARGET_S = 10.0
RESAMPLES = 10_000
REFERENCE_RESAMPLES = 100
STRENGTHS = {"NAT": 1.0, "S1": 0.6, "S2": 0.3, "S3": 0.2, "S4": 0.0, "S5": -0.3, "S6": -0.5, "S7": -1.0}


def _cpu(work) -> tuple[float, object]:
    start = time.process_time()
    result = work()
    return time.process_time() - start, result


def bench_leaderboard() -> dict:
    table = simulate_graded_pairwise(STRENGTHS, n_participants=120, pages_per_participant=20, seed=1)
    votes = read_ratings(io.StringIO(table.to_csv(index=False)))
    ours, _ = _cpu(lambda: leaderboard(votes, resamples=RESAMPLES, seed=0))
    pairs = pair_votes(vote_pages(votes))
    k = len(pairs.systems)
    design = np.zeros((len(pairs.first), k))
    design[np.arange(len(design)), pairs.first], design[np.arange(len(design)), pairs.second] = 1.0, -1.0

    def one_at_a_time():
        for counts in participant_resamples(len(pairs.won), REFERENCE_RESAMPLES, seed=0):
            won, lost, tied = pairs.totals(counts[None])
            x = np.vstack([design[:, 1:], design[:, 1:]])
            y = np.r_[np.ones(len(design)), np.zeros(len(design))]
            weight = np.r_[won[0] + tied[0], lost[0] + tied[0]]
            sm.GLM(y, x, family=sm.families.Binomial(), freq_weights=weight).fit()

    reference, _ = _cpu(one_at_a_time)
    reference *= RESAMPLES / REFERENCE_RESAMPLES
    return {"leaderboard_s": ours, "leaderboard_reference_s": reference, "leaderboard_ratio": reference / ours}


def likert_ratings(participants: int = 150, clips: int = 40, per_system: int = 16, seed: int = 5) -> pd.DataFrame:
    """1-5 ratings of 3 systems from a latent logistic rating with participant and clip effects."""
    rng = np.random.default_rng(seed)
    effects, cuts = {"NAT": 0.0, "A": -0.8, "B": -1.3}, np.array([-2.5, -1.0, 0.5, 2.0])
    u, v = rng.normal(0, 0.8, participants), rng.normal(0, 0.5, (len(effects), clips))
    rows = [(f"p{p}", system, f"{system}_{c}", 1 + int(np.searchsorted(cuts, effect + u[p] + v[s, c] + rng.logistic())))
            for p in range(participants) for s, (system, effect) in enumerate(effects.items())
            for c in rng.choice(clips, per_system, replace=False)]
    return pd.DataFrame(rows, columns=["participant", "system", "stimulus", "value"]).assign(task="t", control_class="c")


def bench_mixed_models() -> dict:
    ratings = likert_ratings()
    linear, _ = _cpu(lambda: crossed_mixed_model(ratings, reference="NAT"))
    ordinal, _ = _cpu(lambda: ordinal_mixed_model(ratings, reference="NAT"))
    model = sm.MixedLM.from_formula("value ~ 0 + C(system)", groups=np.ones(len(ratings)), data=ratings,
                                    vc_formula={"participant": "0 + C(participant)", "stimulus": "0 + C(stimulus)"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reference, _ = _cpu(lambda: model.fit(reml=True, method="lbfgs"))
    return {"ratings": len(ratings), "crossed_lmm_s": linear, "clmm_s": ordinal, "both_s": linear + ordinal,
            "crossed_lmm_reference_s": reference, "crossed_lmm_ratio": reference / linear}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    args = parser.parse_args(argv)
    results = {"machine": describe_machine(), **bench_leaderboard(), **bench_mixed_models(),
               "leaderboard_target_s": LEADERBOARD_TARGET_S, "mixed_models_target_s": MIXED_MODELS_TARGET_S}
    met = results["leaderboard_s"] < LEADERBOARD_TARGET_S and results["both_s"] < MIXED_MODELS_TARGET_S
    if args.json:
        print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in results.items()}, indent=2))
    else:
        print(f"leaderboard, 2,400 votes of 8 systems, {RESAMPLES:,} resamples: {results['leaderboard_s']:.2f} s CPU "
              f"(one GLM per resample, same run: {results['leaderboard_reference_s']:.0f} s, "
              f"{results['leaderboard_ratio']:.0f}x) target {LEADERBOARD_TARGET_S:g} s "
              f"{'ok' if results['leaderboard_s'] < LEADERBOARD_TARGET_S else 'MISSED'}")
        print(f"{results['ratings']:,} ratings: crossed LMM {results['crossed_lmm_s']:.2f} s + CLMM "
              f"{results['clmm_s']:.2f} s = {results['both_s']:.2f} s CPU on one core (statsmodels MixedLM, "
              f"same run: {results['crossed_lmm_reference_s']:.1f} s, {results['crossed_lmm_ratio']:.0f}x the "
              f"LMM) target {MIXED_MODELS_TARGET_S:g} s {'ok' if results['both_s'] < MIXED_MODELS_TARGET_S else 'MISSED'}")
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
