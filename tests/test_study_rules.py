"""One set of study rules: the live flags, the monitor, the in-app report and the command-line
report (given the exported ratings and rules.json) agree, on every design, with rules
other than the defaults."""

from __future__ import annotations

import html
import json
from pathlib import Path

import pytest
from django.test import Client
from django.urls import reverse

from analysis.cli import main as analysis_main
from analysis.ratings.exclusions import ExclusionRules
from analysis.stats.minimums import MODEL_MIN_PARTICIPANTS
from analysis.ratings.schema import read_ratings
from analysis.ratings.report import build_report
from studyapp.models import Participant, System
from studyapp.researchers.results.monitor import study_monitor
from studyapp.researchers.results.reports import html_table, report_folder
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import current_clip, current_page, make_study
from tests.test_study_designs import PAIRWISE, SIDE_BY_SIDE, compare, page_html, page_token, rate_page, watched
from tests.test_study_designs import through_practice as through_page_practice
from tests.test_study_participant import make_shown_long_ago, post, rate_current, through_practice

pytestmark = [pytest.mark.django_db, pytest.mark.slow]

# Each design with rules of its own: who passes them, who fails them, and who the defaults would judge otherwise.
SINGLE_RULES = {"natural_threshold": 4.5, "bad_threshold": 3.0}  # NAT below 4.5 or BAD at 3 or above excludes
SIDE_BY_SIDE_RULES = {**SIDE_BY_SIDE, "natural_threshold": 4.5, "bad_threshold": 3.0}  # on 0-100: 87.5 and 50
PAIRWISE_RULES = {**PAIRWISE, "discard_early": False, "require_full_play": False}  # early answers are kept
APPROPRIATENESS_RULES = {"design": "appropriateness", "discard_early": False, "require_full_play": False}


def value_of(scores: dict[str, int]):
    return lambda clip: scores[clip.stimulus.system.role if clip.stimulus.system.role != System.Role.MODEL
                               else clip.stimulus.system.name]


# A participant's answers: a value per system (single, side by side), or which side to prefer.
SCORES = {
    "careful": {System.Role.NATURAL: 5, System.Role.BAD: 1, "MoGlow": 4, "RNN": 2},
    "nat-4": {System.Role.NATURAL: 4, System.Role.BAD: 1, "MoGlow": 3, "RNN": 2},  # excluded: NAT below 4.5
    "bad-3": {System.Role.NATURAL: 5, System.Role.BAD: 3, "MoGlow": 5, "RNN": 3},  # excluded: BAD at 3
    "fair": {System.Role.NATURAL: 5, System.Role.BAD: 2, "MoGlow": 3, "RNN": 3},
}


def sliders(scores: dict) -> dict:
    """The 1-5 scores on 0-100 sliders."""
    return {system: 25 * (value - 1) for system, value in scores.items()}


def take_part(study, pid: str, answers) -> None:
    client = Client()
    if study.design == "single":
        participant = through_practice(client, study, pid)
        while (clip := current_clip(participant)) is not None:
            rate_current(client, study, participant, value_of(answers)(clip))
        return
    participant = through_page_practice(client, study, pid)
    early = {"ended_s-1": "", "ended_s-2": ""}  # the browser saw no end: answered early
    while page := current_page(participant):
        if study.design == "appropriateness":
            answer_appropriateness(client, study, participant, page, answers, early)
        elif study.design == "side-by-side":
            rate_page(client, study, participant, value_of(sliders(answers)))
        else:
            roles = [a.stimulus.system.role for a in page]
            prefer_bad = answers == "prefers BAD" and System.Role.BAD in roles
            side = "left" if (roles[0] == System.Role.BAD) == prefer_bad else "right"
            compare(client, study, participant, side, **(early if answers == "hasty" else {}))


def answer_appropriateness(client: Client, study, participant, page, answers: str, early: dict) -> None:
    """The matched clip clearly preferred, but on a check page by "careless" (the
    mismatched one), and answered before the clips could end by "hasty"."""
    matched = "left" if page[0].stimulus.shown_control_id is None else "right"
    side = {"left": "right", "right": "left"}[matched] if answers == "careless" and page[0].is_check else matched
    html = page_html(client, study)
    make_shown_long_ago(participant)
    response = post(client, study, "rate", page=page_token(html), answer=side, strength=2,
                    **{**watched((1, 2)), **(early if answers == "hasty" else {})})
    assert response.status_code == 302, response.content[:300]


def populate(study) -> None:
    if study.design == "appropriateness":
        for pid in ("careful", "careless", "hasty", "other"):
            take_part(study, pid, pid)
        return
    if study.design == "pairwise":
        for pid, answers in (("careful", "careful"), ("prefers-bad", "prefers BAD"), ("hasty", "hasty"),
                             ("other", "careful")):
            take_part(study, pid, answers)
        return
    for pid, scores in SCORES.items():
        take_part(study, pid, scores)


def make_ruled_study(fields: dict):
    if fields.get("design") == "appropriateness":
        return make_appropriateness_study(pages_per_participant=6, training_clips=0,
                                          **{k: v for k, v in fields.items() if k != "design"})
    return make_study(controls=3, clips_per_participant=7, ratings_per_stimulus=10, training_clips=0, **fields)


def in_app_report(client: Client, study, settings) -> Path:
    response = client.post(reverse("study-report", args=[study.pk]))
    assert response.status_code == 302 and response["Location"].startswith("/analysis/"), response
    return report_folder(settings.MEDIA_ROOT, response["Location"].strip("/").split("/")[-1])


def command_line_report(client: Client, study, tmp_path: Path) -> Path:
    """``python -m analysis report`` on the downloaded ratings.csv and rules.json."""
    (tmp_path / "ratings.csv").write_bytes(client.get(reverse("study-export", args=[study.pk])).content)
    (tmp_path / "rules.json").write_bytes(client.get(reverse("study-rules", args=[study.pk])).content)
    out = tmp_path / "report"
    assert analysis_main(["report", str(tmp_path / "ratings.csv"), "--rules", str(tmp_path / "rules.json"),
                          "--out", str(out)]) == 0
    return out


def test_the_in_app_report_excludes_the_participants_the_study_excludes(settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(controls=3, clips_per_participant=7, ratings_per_stimulus=10, training_clips=0, **SINGLE_RULES)
    populate(study)
    client = Client()
    client.force_login(study.owner)
    removed = json.loads((in_app_report(client, study, settings) / "tables" / "exclusions.json").read_text())
    excluded = Participant.objects.filter(study=study, excluded=True).count()
    assert sum(row["participants_removed"] for row in removed) == excluded == 2  # nat-4 and bad-3


@pytest.mark.parametrize("fields", [SINGLE_RULES, SIDE_BY_SIDE_RULES, PAIRWISE_RULES, APPROPRIATENESS_RULES],
                         ids=["single", "side-by-side", "pairwise", "appropriateness"])
def test_monitor_in_app_report_and_command_line_report_agree_under_the_studys_rules(fields, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_ruled_study(fields)
    populate(study)
    client = Client()
    client.force_login(study.owner)

    rules = ExclusionRules.from_json(client.get(reverse("study-rules", args=[study.pk])).content.decode())
    assert (rules.bad_at_or_above, rules.natural_below, rules.discard_early) == (
        study.bad_threshold, study.natural_threshold, study.discard_early)
    app, cli = in_app_report(client, study, settings), command_line_report(client, study, tmp_path)
    tables = sorted(path.name for path in (app / "tables").iterdir())
    assert tables == sorted(path.name for path in (cli / "tables").iterdir()) and "exclusions.csv" in tables
    for name in tables:
        assert (app / "tables" / name).read_bytes() == (cli / "tables" / name).read_bytes(), name

    excluded = {p.platform_id for p in Participant.objects.filter(study=study, excluded=True)}
    assert excluded == {"pairwise": {"prefers-bad"}, "appropriateness": {"careless"}}.get(study.design, {"nat-4", "bad-3"})
    removed = json.loads((app / "tables" / "exclusions.json").read_text())
    monitor = study_monitor(study)
    assert monitor.participants_excluded == sum(row["participants_removed"] for row in removed) == len(excluded)
    page = client.get(f"/analysis/{app.name}/").content.decode()
    assert f"below {study.natural_threshold:g}" in page and 'id="rules"' in page  # the report states its rules

    # The monitor's summary is the report's own table, on the same kept ratings.
    report = build_report(read_ratings(tmp_path / "ratings.csv"), rules=rules)
    if study.design == "single":
        means = report.means.set_index("system")
        assert {row.system for row in monitor.means} == {*means.index, "BAD"}  # the monitor shows BAD's too
        for row in (row for row in monitor.means if row.system in means.index):
            assert (row.n, row.mean, row.ci_low) == pytest.approx(
                (means.loc[row.system, "n"], means.loc[row.system, "mean"], means.loc[row.system, "ci_low"]))
    else:
        name = {"side-by-side": "system_medians_means", "pairwise": "preference_pairs",
                "appropriateness": "matched_preference"}[study.design]
        assert monitor.tables[0][1] == html_table(report.table(name))
    if study.design in ("pairwise", "appropriateness"):  # early answers kept under these rules: the hasty pages count
        assert report.flagged["discarded_early"].sum() == 0 and report.flagged["answered_before_end"].any()


RATER_TABLES = ("crossed_mixed_estimates", "crossed_mixed_contrasts", "crossed_mixed_variance",
                "ordinal_mixed_thresholds", "ordinal_mixed_effects", "ordinal_mixed_random", "rater_agreement")


def rater_models_three_ways(study, settings, tmp_path: Path):
    """The study's rater- and clip-aware models as the researcher meets them: the in-app
    report's folder and page, the command line's models of the downloaded ratings and
    rules, and the monitor."""
    client = Client()
    client.force_login(study.owner)
    app = in_app_report(client, study, settings)
    page = client.get(f"/analysis/{app.name}/").content.decode()
    (tmp_path / "ratings.csv").write_bytes(client.get(reverse("study-export", args=[study.pk])).content)
    rules = ExclusionRules.from_json(client.get(reverse("study-rules", args=[study.pk])).content.decode())
    models = build_report(read_ratings(tmp_path / "ratings.csv"), rules=rules).rater_models
    return app, page, models, study_monitor(study)


@pytest.mark.parametrize("fields", [SINGLE_RULES, SIDE_BY_SIDE_RULES], ids=["single", "side-by-side"])
def test_the_monitor_and_the_in_app_report_show_the_rater_and_clip_aware_models(fields, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(controls=3, clips_per_participant=7, ratings_per_stimulus=10, training_clips=0, **fields)
    populate(study)
    for n in range(2):  # five kept participants: enough for the models (analysis.stats.minimums)
        for pid in ("careful", "fair"):
            take_part(study, f"{pid}-{n}", SCORES[pid])
    app, page, rater_models, shown = rater_models_three_ways(study, settings, tmp_path)
    models, monitor = rater_models.tables(), dict(shown.tables)
    # No cumulative link model on either design: the side-by-side sliders (0-100) have too
    # many points, and the single clips' kept raters gave NAT 5 and no other system 5, which
    # separates the systems (the log-odds have no finite estimate). Both places say why.
    expected = [n for n in RATER_TABLES if not n.startswith("ordinal")]
    assert [name for name, (_, table) in models.items() if len(table)] == list(expected)
    why = next(note for note in rater_models.notes if note.startswith("No cumulative link mixed model"))
    assert ("separate the systems" in why) == (study.design == "single")
    assert why in shown.analysis_notes and html.escape(why) in page
    for name in expected:
        title, table = models[name]
        assert (app / "tables" / f"{name}.csv").is_file()
        assert html.escape(title) in page and html_table(table) in page  # the report page
        assert monitor[title] == html_table(table)  # the monitor: the same model of the same ratings


def test_ratings_that_overlap_get_the_cumulative_link_model_in_the_monitor_and_the_report(settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(controls=3, clips_per_participant=7, ratings_per_stimulus=10, training_clips=0,
                       natural_threshold=1.0)  # nobody excluded: every system's ratings spread over 2-5
    for n in range(MODEL_MIN_PARTICIPANTS):
        client = Client()
        participant = through_practice(client, study, f"varied-{n}")
        rated = 0
        while (clip := current_clip(participant)) is not None:
            bad = clip.stimulus.system.role == System.Role.BAD
            rate_current(client, study, participant, 1 if bad else 2 + (rated + n) % 4)
            rated += 1
    app, page, rater_models, shown = rater_models_three_ways(study, settings, tmp_path)
    models, monitor = rater_models.tables(), dict(shown.tables)
    for name in ("ordinal_mixed_thresholds", "ordinal_mixed_effects", "ordinal_mixed_random"):
        title, table = models[name]
        assert len(table) and (app / "tables" / f"{name}.csv").is_file()
        assert html.escape(title) in page and html_table(table) in page
        assert monitor[title] == html_table(table)
