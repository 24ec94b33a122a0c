"""The per-clip correlation of the objective metrics with the raters, for a study of the
app: its ratings export names each clip by its motion files' name (``clip``) beside the
opaque token its video is served under, so ``python -m analysis report --motion`` matches
every rated clip to the motion the study's motion export writes for it."""

from __future__ import annotations

import csv
import io

import numpy as np
import pandas as pd
import pytest
from django.test import Client
from scipy import stats as sps

from analysis.cli import main
from analysis.motion.motion_io import save_clips
from studyapp.models import Stimulus, System
from studyapp.researchers.results.export import ratings_csv
from studyapp.stimuli.motion_export import clip_name, folder_name
from tests.study_fixtures import current_clip, make_study
from tests.test_study_participant import rate_current, through_practice

pytestmark = pytest.mark.django_db

# Every participant's rating of each system's clip of control-0 .. control-3 (BAD's: 1).
RATED = {"NAT": [5, 4, 5, 4], "MoGlow": [4, 3, 3, 4], "RNN": [2, 1, 3, 2]}


def test_the_export_names_each_clip_as_the_motion_export_names_its_files_and_never_by_its_token():
    study = make_study(controls=2, clips_per_participant=4, bad_checks=0, natural_checks=0, training_clips=0)
    client = Client()
    participant = through_practice(client, study)
    for _ in range(4):
        rate_current(client, study, participant, 3)
    rows = list(csv.DictReader(io.StringIO(ratings_csv(study).decode())))
    tokens = {s.token: s for s in Stimulus.objects.filter(study=study)}
    assert len(rows) == 4 and all(row["clip"] == clip_name(tokens[row["stimulus"]]) for row in rows)
    assert {row["clip"] for row in rows} <= {c.export_id or f"control-{c.pk}" for c in study.controls.all()}
    assert not {row["clip"] for row in rows} & set(tokens)


def test_an_app_studys_report_with_its_motion_has_a_per_clip_correlation_over_every_rated_clip(tmp_path, motion_data):
    from generation.motion import load_motion

    study = make_study(controls=4, clips_per_participant=13, bad_checks=1, natural_checks=0, training_clips=0,
                       ratings_per_stimulus=10)
    controls = {c.pk: k for k, c in enumerate(study.controls.order_by("name"))}
    for pid in ("p1", "p2", "p3"):
        client = Client()
        participant = through_practice(client, study, pid)
        while (assignment := current_clip(participant)) is not None:
            system = assignment.stimulus.system
            value = 1 if system.role == System.Role.BAD else RATED[system.name][controls[assignment.stimulus.control_id]]
            assert rate_current(client, study, participant, value).status_code == 302
    (tmp_path / "ratings.csv").write_bytes(ratings_csv(study))

    # Each clip's motion where the study's motion export puts it: the worse its rating, the shakier.
    walk = load_motion(sorted((motion_data / "data").glob("dataset-1_walk_*_001.bvh"))[0])
    rng = np.random.default_rng(0)
    for stimulus in Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD).select_related(
            "system", "control"):
        k = controls[stimulus.control_id]
        shake = 6 - RATED[stimulus.system.name][k] + 0.1 * k + 0.01 * len(stimulus.system.name)  # no two alike
        folder = tmp_path / "motion" / folder_name(stimulus.system)
        folder.mkdir(parents=True, exist_ok=True)
        positions = walk.positions[:120] + rng.normal(0, shake, walk.positions[:120].shape)
        save_clips(folder / f"{clip_name(stimulus)}.npz", positions, walk.fps, walk.skeleton.names,
                   walk.skeleton.parents, walk.skeleton.offsets, system=stimulus.system.export_name)

    assert main(["report", str(tmp_path / "ratings.csv"), "--motion", str(tmp_path / "motion"),
                 "--out", str(tmp_path / "report")]) == 0
    agreement = pd.read_csv(tmp_path / "report" / "tables" / "metric_agreement.csv").set_index("metric")
    metrics = pd.read_csv(tmp_path / "report" / "tables" / "clip_metrics.csv")
    assert (agreement["n_clips"] == 12).all()  # every rated clip of NAT, MoGlow and RNN matched to its motion
    ratings = pd.read_csv(tmp_path / "ratings.csv")
    mean_rating = ratings.groupby(["system", "clip"])["value"].mean().rename("rating")
    for metric, row in agreement.iterrows():
        joined = metrics[metrics["metric"] == metric].join(mean_rating, on=["system", "stimulus"], how="inner")
        expected = sps.kendalltau(joined["value"], joined["rating"])
        assert len(joined) == 12 and (row["clip_tau"], row["clip_p"]) == pytest.approx(
            (expected.statistic, expected.pvalue))
    assert agreement.loc["joint_acceleration", "clip_tau"] < -0.6  # the shakier clips were rated worse
