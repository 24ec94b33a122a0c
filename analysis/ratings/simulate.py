"""Synthetic ratings in the schema of `analysis.ratings.schema`, for power analysis and testing.

One function per design (`analysis.designs`), each drawing a study with known effects:

- `simulate_ratings` (single): every participant has their own offset (rater
  leniency), systems have true means on a 1-5 scale, ratings are rounded and clipped to
  the scale;
- `simulate_side_by_side`: pages of all systems' clips for one control, rated 0-100;
  besides the rater's offset, each control shifts all clips on its page alike (some
  controls are harder), which is what pairing by page removes;
- `simulate_pairwise`: pages of two systems, preferences drawn from a Bradley-Terry
  model with known strengths, a share of pages answered "no preference", sides random.
- `simulate_appropriateness`: pages of one system's matched and mismatched clips, the
  matched one preferred with a known probability per system, BAD attention pages that
  attentive participants get right.

In each, a chosen share of participants is inattentive (answers at random, attention
checks included) and a share of answers is given before the clip ended. Seeded: the same
arguments give the same table.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations

import numpy as np
import pandas as pd


def simulate_ratings(system_means: Mapping[str, float], n_ratings: int,
                     tasks: Sequence[str] = ("locomotion",),
                     control_classes: Sequence[str] = ("held-out", "synthetic"),
                     ratings_per_participant: int = 50, stimuli_per_system: int = 20,
                     participant_sd: float = 0.5, rating_sd: float = 0.9,
                     inattentive_share: float = 0.05, early_share: float = 0.02,
                     bad_mean: float = 1.3, seed: int = 0) -> pd.DataFrame:
    """About ``n_ratings`` rows on a 1-5 scale, BAD attention checks included.

    Inattentive participants rate uniformly at random, BAD clips included, so most of
    them trip the attention rule, as in a real crowd study. As in one, a participant
    rates a stimulus at most once (repeated draws are dropped).
    """
    rng = np.random.default_rng(seed)
    systems = [*system_means, "BAD"]
    means = np.array([*system_means.values(), bad_mean])
    n_participants = max(1, n_ratings // ratings_per_participant)
    participant = rng.integers(0, n_participants, n_ratings)
    task = rng.integers(0, len(tasks), n_ratings)
    control = rng.integers(0, len(control_classes), n_ratings)
    system = rng.integers(0, len(systems), n_ratings)
    stimulus = rng.integers(0, stimuli_per_system, n_ratings)
    offset = rng.normal(0.0, participant_sd, n_participants)
    raw = means[system] + offset[participant] + rng.normal(0.0, rating_sd, n_ratings)
    inattentive = rng.random(n_participants) < inattentive_share
    raw = np.where(inattentive[participant], rng.uniform(0.5, 5.5, n_ratings), raw)
    value = np.clip(np.rint(raw), 1, 5).astype(np.int64)
    duration = 10.0
    early = rng.random(n_ratings) < early_share
    played = np.where(early, rng.uniform(1.0, duration - 1.0, n_ratings), duration)
    names = np.array(systems)
    clip = np.char.add(np.char.add(names[system], "_"), np.asarray(control_classes)[control])
    table = pd.DataFrame({
        "participant": np.char.add("p", participant.astype(str)),
        "system": names[system],
        "stimulus": np.char.add(np.char.add(clip, "_"), stimulus.astype(str)),
        "task": np.asarray(tasks)[task],
        "control_class": np.asarray(control_classes)[control],
        "value": value,
        "scale_min": 1,
        "scale_max": 5,
        "clip_duration_s": duration,
        "played_until_s": played,
    })
    return table.drop_duplicates(["participant", "task", "stimulus"]).reset_index(drop=True)


def _early_playback(rng: np.random.Generator, n: int, early_share: float,
                    duration: float = 10.0) -> np.ndarray:
    early = rng.random(n) < early_share
    return np.where(early, rng.uniform(1.0, duration - 1.0, n), duration)


def simulate_side_by_side(system_means: Mapping[str, float], n_participants: int,
                          pages_per_participant: int = 10, controls: int = 40,
                          participant_sd: float = 8.0, control_sd: float = 6.0,
                          rating_sd: float = 15.0, inattentive_share: float = 0.05,
                          early_share: float = 0.02, task: str = "gesture",
                          control_class: str = "held-out", seed: int = 0) -> pd.DataFrame:
    """Side-by-side pages on a 0-100 slider: every page shows every system once.

    ``system_means`` are the true means on 0-100 (list NAT and BAD among them to have
    attention checks). A participant sees ``pages_per_participant`` different controls.
    """
    if pages_per_participant > controls:
        raise ValueError("a participant sees each control at most once: pages_per_participant "
                         f"({pages_per_participant}) must not exceed controls ({controls})")
    rng = np.random.default_rng(seed)
    systems = np.array(list(system_means))
    means = np.array(list(system_means.values()), dtype=np.float64)
    k = len(systems)
    control_shift = rng.normal(0.0, control_sd, controls)
    rows = []
    for p in range(n_participants):
        offset = rng.normal(0.0, participant_sd)
        inattentive = rng.random() < inattentive_share
        for c in rng.choice(controls, pages_per_participant, replace=False):
            raw = means + offset + control_shift[c] + rng.normal(0.0, rating_sd, k)
            if inattentive:
                raw = rng.uniform(0.0, 100.0, k)
            rows.append(pd.DataFrame({
                "participant": f"p{p}", "system": systems, "stimulus": np.char.add(systems, f"_c{c}"),
                "page": f"c{c}", "position": rng.permutation(k) + 1,
                "value": np.clip(np.rint(raw), 0, 100).astype(np.int64)}))
    table = pd.concat(rows, ignore_index=True)
    table.insert(0, "design", "side-by-side")
    table["task"], table["control_class"] = task, control_class
    table["scale_min"], table["scale_max"] = 0, 100
    table["clip_duration_s"] = 10.0
    table["played_until_s"] = _early_playback(rng, len(table), early_share)
    return table


def simulate_pairwise(strengths: Mapping[str, float], n_participants: int,
                      pages_per_participant: int = 20,
                      pairs: Sequence[tuple[str, str]] | None = None,
                      no_preference_share: float = 0.1, inattentive_share: float = 0.05,
                      early_share: float = 0.02, task: str = "gesture",
                      control_class: str = "held-out", controls: int = 40,
                      seed: int = 0) -> pd.DataFrame:
    """Pairwise pages with preferences from a Bradley-Terry model.

    ``strengths`` are log-strengths: system i beats j with probability
    1 / (1 + exp(s_j - s_i)). ``pairs`` defaults to every pair of systems; each page
    draws one at random, with sides at random. A page is answered "none" with
    probability ``no_preference_share``; inattentive participants answer at random.
    """
    rng = np.random.default_rng(seed)
    pairs = list(pairs) if pairs is not None else list(combinations(strengths, 2))
    rows = []
    for p in range(n_participants):
        inattentive = rng.random() < inattentive_share
        for page in range(pages_per_participant):
            a, b = pairs[rng.integers(len(pairs))]
            left, right = (a, b) if rng.random() < 0.5 else (b, a)
            p_left = 1.0 / (1.0 + np.exp(strengths[right] - strengths[left]))
            if rng.random() < no_preference_share:
                answer = "none"
            elif inattentive:
                answer = "left" if rng.random() < 0.5 else "right"
            else:
                answer = "left" if rng.random() < p_left else "right"
            control = f"c{rng.integers(controls)}"
            for side, system in (("left", left), ("right", right)):
                rows.append({"participant": f"p{p}", "system": system,
                             "stimulus": f"{system}_{control}", "page": f"q{page}",
                             "side": side, "answer": answer})
    table = pd.DataFrame(rows)
    table.insert(0, "design", "pairwise")
    table["task"], table["control_class"] = task, control_class
    table["clip_duration_s"] = 10.0
    table["played_until_s"] = _early_playback(rng, len(table), early_share)
    return table


def simulate_appropriateness(prefer_matched: Mapping[str, float], n_participants: int,
                             pages_per_participant: int = 24, no_preference_share: float = 0.15,
                             clear_share: float = 0.5, attention_pages: int = 2,
                             inattentive_share: float = 0.05, early_share: float = 0.02,
                             task: str = "locomotion", control_class: str = "held-out",
                             controls: int = 40, seed: int = 0) -> pd.DataFrame:
    """Appropriateness pages: each shows one system's matched and mismatched clips, sides at random.

    A page is answered "none" with probability ``no_preference_share``; otherwise the
    matched clip is preferred with the system's probability in ``prefer_matched``,
    clearly (strength 2) with probability ``clear_share``, else slightly. Every
    participant also sees ``attention_pages`` BAD pages, where the matched clip is
    always preferred by the attentive; inattentive participants answer every page at
    random. So the share preferring matched, ties split, is
    ``p (1 - t) + t / 2`` and the mean score ``(2 p - 1)(1 - t)(1 + c)`` for p the
    system's probability, t the no-preference share and c the clear share.
    """
    rng = np.random.default_rng(seed)
    systems = list(prefer_matched)
    rows = []
    for p in range(n_participants):
        inattentive = rng.random() < inattentive_share
        shown = [systems[rng.integers(len(systems))] for _ in range(pages_per_participant)]
        for page, system in enumerate([*shown, *["BAD"] * attention_pages]):
            left_matched = rng.random() < 0.5
            if inattentive:
                answer = ("left", "right", "none")[rng.integers(3)]
            elif system != "BAD" and rng.random() < no_preference_share:
                answer = "none"
            else:
                chose_matched = system == "BAD" or rng.random() < prefer_matched[system]
                answer = "left" if chose_matched == left_matched else "right"
            strength = "" if answer == "none" else 2 if rng.random() < clear_share else 1
            control = f"c{rng.integers(controls)}"
            for side, matched in (("left", left_matched), ("right", not left_matched)):
                clip = f"{system}_{control}" if matched else f"{system}_{control}_mismatched"
                rows.append({"participant": f"p{p}", "system": system, "stimulus": clip, "page": f"q{page}",
                             "side": side, "matched": matched, "answer": answer, "strength": strength})
    table = pd.DataFrame(rows)
    table.insert(0, "design", "appropriateness")
    table["task"], table["control_class"] = task, control_class
    table["clip_duration_s"] = 10.0
    table["played_until_s"] = np.repeat(_early_playback(rng, len(table) // 2, early_share), 2)
    return table
