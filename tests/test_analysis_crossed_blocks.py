"""The crossed block matrix ``M = [[diag(a), C], [C', diag(d)]]`` that both crossed mixed
models factorise: its log-determinant, solves and inverse blocks equal those of M built
dense and handled by numpy, whether C is held dense or as sums over the occurring pairs,
and whichever factor has fewer levels."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import analysis.raters.crossed_design as crossed_design
from analysis.raters.crossed_design import CrossedBlocks, crossed_layout


def sparse_ratings(participants: int, stimuli: int, per_participant: int, seed: int) -> pd.DataFrame:
    """Each participant rates a few stimuli, some twice (a pair then holds two ratings)."""
    rng = np.random.default_rng(seed)
    rows = [(f"p{p}", f"s{s}") for p in range(participants)
            for s in rng.choice(stimuli, per_participant, replace=False)]
    rows += rows[:5]
    return pd.DataFrame(rows, columns=["participant", "stimulus"]).assign(system="A")


@pytest.mark.parametrize("participants, stimuli", [(12, 30), (30, 12)])  # participants or stimuli the smaller block
@pytest.mark.parametrize("dense", [True, False])
def test_factorisation_equals_a_dense_computation_whichever_way_c_is_held(monkeypatch, participants, stimuli, dense):
    monkeypatch.setattr(crossed_design, "_DENSE_ADVANTAGE", 10**9 if dense else 0)
    layout = crossed_layout(sparse_ratings(participants, stimuli, 4, seed=participants), None)
    assert (layout.pattern.couples is None) == dense
    rng = np.random.default_rng(1)
    q_p, q_s = layout.q
    per_pair = rng.uniform(0.1, 1.0, len(layout.pair_participant))
    c = np.zeros((q_p, q_s))
    c[layout.pair_participant, layout.pair_stimulus] = per_pair
    # diagonally dominant, hence positive definite
    a, d = 1.0 + c.sum(axis=1) + rng.uniform(0, 1, q_p), 1.0 + c.sum(axis=0) + rng.uniform(0, 1, q_s)
    m = np.block([[np.diag(a), c], [c.T, np.diag(d)]])
    blocks = CrossedBlocks(layout, a, per_pair, d)

    assert blocks.logdet() == pytest.approx(np.linalg.slogdet(m)[1], rel=1e-12)
    for right in (rng.normal(size=q_p + q_s), rng.normal(size=(q_p + q_s, 3))):
        first, second = blocks.solve(right[:q_p], right[q_p:])
        np.testing.assert_allclose(np.concatenate([first, second]), np.linalg.solve(m, right), rtol=1e-10, atol=1e-12)
    inverse = np.linalg.inv(m)
    participant_diagonal, stimulus_diagonal, at_pairs = blocks.inverse_blocks()
    np.testing.assert_allclose(participant_diagonal, np.diag(inverse)[:q_p], rtol=1e-10)
    np.testing.assert_allclose(stimulus_diagonal, np.diag(inverse)[q_p:], rtol=1e-10)
    np.testing.assert_allclose(at_pairs, inverse[layout.pair_participant, q_p + layout.pair_stimulus], rtol=1e-9,
                               atol=1e-14)


def test_a_design_of_few_ratings_per_participant_keeps_c_as_sums_and_a_compact_one_dense():
    assert crossed_layout(sparse_ratings(400, 300, 3, seed=0), None).pattern.couples is not None
    assert crossed_layout(sparse_ratings(40, 30, 20, seed=0), None).pattern.couples is None
