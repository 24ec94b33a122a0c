"""Synthetic ratings in the schema of `analysis.ratings`, for power analysis and testing.

`simulate_ratings` draws a study with known effects: every participant has their own
offset (rater leniency), systems have true means on a 1-5 scale, ratings are rounded
and clipped to the scale, and a chosen share of participants fail attention checks or
answer early. Seeded: the same arguments give the same table.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

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
    them trip the attention rule, as in a real crowd study.
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
    return pd.DataFrame({
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
