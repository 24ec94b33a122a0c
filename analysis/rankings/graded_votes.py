"""Five-level pairwise answers drawn from known strengths, for simulations and tests.

A graded pairwise page asks which clip is better on five levels: the left clip clearly
or slightly better, no preference, the right clip slightly or clearly better. In the
ratings table that is ``answer`` (``left`` / ``right`` / ``none``) and ``strength``
(1 = slightly, 2 = clearly; empty for ``none``), see docs/ratings-schema.md.

The leaderboard (`analysis.rankings.leaderboard`) counts a clear win as 4 wins, a slight win as 2
and a page without preference as 1 win for each side. The answers drawn here are built
so that this weighted Bradley-Terry model holds in expectation for every pair, whatever
the pairs shown: with ``d = b_left - b_right`` (log-strengths),

    E[wins credited to the left clip] = sigmoid(d) * E[total weight of the page],

so the weighted fit estimates the true strengths under any pairing design (uniform or
adaptive), which is what lets the simulations check coverage against the truth. Per page:

- no preference with probability ``P_tie = tie_peak * 4 sigmoid(d) sigmoid(-d)``: likeliest
  between equal systems, vanishing between distant ones;
- otherwise a clear answer with probability ``sigmoid(|d|)`` (from 1/2 between equals
  towards 1 between distant systems), else a slight one;
- the direction: left with probability
  ``q = (sigmoid(d) (4 P_clear + 2 P_slight + 2 P_tie) - P_tie) / (4 P_clear + 2 P_slight)``,
  which solves the equation above; it lies in [0, 1] for ``tie_peak <= 1/3``.

With ``graded=False`` the page has the plain three answers: a stated preference carries
no strength (the leaderboard counts it as clear, weight 4) and P_slight = 0.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations

import numpy as np
import pandas as pd

MAX_TIE_PEAK = 1.0 / 3.0


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * np.asarray(x, dtype=np.float64)))


def answer_probabilities(d, tie_peak: float = 0.25, graded: bool = True) -> np.ndarray:
    """P(level) for levels (-2, -1, 0, 1, 2): right clearly, right slightly, no preference,
    left slightly, left clearly; one row per log-strength difference ``d`` (left - right)."""
    if not 0.0 <= tie_peak <= MAX_TIE_PEAK:
        raise ValueError(f"tie_peak must lie in [0, 1/3] for the answers to stay probabilities; got {tie_peak}")
    d = np.asarray(d, dtype=np.float64)
    s = _sigmoid(d)
    tie = tie_peak * 4.0 * s * (1.0 - s)
    clear = (1.0 - tie) * (_sigmoid(np.abs(d)) if graded else 1.0)
    slight = 1.0 - tie - clear
    left = (s * (4.0 * clear + 2.0 * slight + 2.0 * tie) - tie) / (4.0 * clear + 2.0 * slight)
    return np.stack([(1 - left) * clear, (1 - left) * slight, tie, left * slight, left * clear], axis=-1)


def draw_levels(rng: np.random.Generator, d, tie_peak: float = 0.25, graded: bool = True) -> np.ndarray:
    """One answer level (-2 .. 2) per difference in ``d``."""
    cumulative = np.cumsum(answer_probabilities(d, tie_peak, graded), axis=-1)
    u = rng.random(np.shape(d))
    return (u[..., None] > cumulative[..., :-1]).sum(axis=-1) - 2


def level_answers(levels: np.ndarray, graded: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The ratings table's ``answer`` and ``strength`` (nullable) of answer levels."""
    answer = np.where(levels > 0, "left", np.where(levels < 0, "right", "none"))
    strength = pd.array(np.abs(levels), dtype="Int64")
    strength[(levels == 0) | (not graded)] = pd.NA
    return answer, strength


def simulate_graded_pairwise(strengths: Mapping[str, float], n_participants: int,
                             pages_per_participant: int = 20,
                             pairs: Sequence[tuple[str, str]] | None = None,
                             tie_peak: float = 0.25, graded: bool = True,
                             task: str = "gesture", control_class: str = "held-out",
                             controls: int = 40, seed: int = 0) -> pd.DataFrame:
    """A pairwise ratings table (two rows per page) with five-level answers.

    ``strengths`` are log-strengths. Each page shows a pair drawn uniformly from ``pairs``
    (default: every pair), sides at random, for a random control. Every participant is
    attentive and answers after the clips end (`analysis.ratings.simulate.simulate_pairwise` draws
    plain answers with inattentive raters and early answers).
    """
    rng = np.random.default_rng(seed)
    names = list(strengths)
    index = {name: i for i, name in enumerate(names)}
    pairs = list(pairs) if pairs is not None else list(combinations(names, 2))
    pair_index = np.array([[index[a], index[b]] for a, b in pairs])
    log_strength = np.array([strengths[n] for n in names], dtype=np.float64)
    n = n_participants * pages_per_participant
    chosen = pair_index[rng.integers(len(pairs), size=n)]
    swap = rng.random(n) < 0.5
    left = np.where(swap, chosen[:, 1], chosen[:, 0])
    right = np.where(swap, chosen[:, 0], chosen[:, 1])
    levels = draw_levels(rng, log_strength[left] - log_strength[right], tie_peak, graded)
    answer, strength = level_answers(levels, graded)
    control = rng.integers(controls, size=n)
    participant = np.repeat(np.arange(n_participants), pages_per_participant)
    page = np.tile(np.arange(pages_per_participant), n_participants)
    system = np.array(names)
    sides = []
    for side, which in (("left", left), ("right", right)):
        sides.append(pd.DataFrame({
            "participant": np.char.add("p", participant.astype(str)),
            "page": np.char.add("q", page.astype(str)),
            "system": system[which],
            "stimulus": np.char.add(np.char.add(system[which], "_c"), control.astype(str)),
            "side": side, "answer": answer, "strength": strength}))
    table = pd.concat(sides).sort_index(kind="stable").reset_index(drop=True)
    table.insert(0, "design", "pairwise")
    table["task"], table["control_class"] = task, control_class
    return table
