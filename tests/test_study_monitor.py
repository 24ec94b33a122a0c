"""The monitor page and the ratings export, checked against the stored ratings.

Means and confidence intervals are recomputed here from the database rows with
scipy.stats.t, independently of ``analysis.stats.anova``.
"""

from __future__ import annotations

import csv
import io
import math

import pytest
from django.utils import timezone
from scipy import stats

from analysis.ratings.exclusions import scaled_threshold
from analysis.stats.minimums import INTERVAL_FEW_PARTICIPANTS, MODEL_MIN_PARTICIPANTS
from studyapp.models import Assignment, Participant, Rating, Stimulus
from studyapp.researchers.results.export import EXPORT_COLUMNS
from studyapp.researchers.results.monitor import study_monitor
from tests.study_fixtures import make_study

# participant -> ratings as (system, control index, value, answered before the clip ended)
RATINGS = {
    "p1": [("MoGlow", 0, 4, False), ("MoGlow", 1, 3, False), ("NAT", 0, 5, False), ("BAD", 0, 1, False)],
    "p2": [("MoGlow", 0, 5, False), ("MoGlow", 2, 4, False), ("NAT", 1, 4, False), ("RNN", 0, 2, False)],
    "p3": [("MoGlow", 1, 1, False), ("NAT", 2, 5, False), ("BAD", 1, 5, False)],  # rates BAD high: excluded
    "p4": [("MoGlow", 2, 2, True), ("NAT", 0, 4, False), ("BAD", 2, 2, False)],  # one early answer: discarded
}


def store_ratings(study) -> None:
    now = timezone.now()
    for platform_id, ratings in RATINGS.items():
        participant = Participant.objects.create(study=study, platform_id=platform_id, finished_at=now)
        for position, (system, control, value, early) in enumerate(ratings):
            stimulus = Stimulus.objects.get(study=study, system__name=system, control__name=f"control-{control}")
            assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=position, page=position,
                                                   shown_at=now)
            Rating.objects.create(assignment=assignment, value=value, answered_before_end=early)
            if system == "BAD" and value >= scaled_threshold(study.bad_threshold, study.scale_min, study.scale_max):
                participant.excluded, participant.exclusion_reason = True, "rated a BAD clip high"
        participant.save()
    Participant.objects.create(study=study, platform_id="p5", refused_early=2)  # started, refused twice, not finished


@pytest.fixture
def study(client, db, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    study = make_study(controls=3)
    client.force_login(study.owner)
    store_ratings(study)
    return study


def test_the_csv_export_has_exactly_the_stored_ratings(client, study):
    response = client.get(f"/studies/{study.pk}/ratings.csv")
    assert response.status_code == 200 and response["Content-Type"] == "text/csv"
    rows = list(csv.DictReader(io.StringIO(response.content.decode())))
    assert tuple(rows[0]) == EXPORT_COLUMNS
    codes = dict(Participant.objects.values_list("code", "platform_id"))
    exported = sorted((codes[r["participant"]], r["system"], r["stimulus"], int(r["value"])) for r in rows)
    stored = sorted((r.assignment.participant.platform_id, r.assignment.stimulus.system.export_name,
                     r.assignment.stimulus.token, r.value) for r in Rating.objects.select_related(
                         "assignment__participant", "assignment__stimulus__system"))
    assert exported == stored and len(rows) == sum(len(r) for r in RATINGS.values()) == 14
    assert {codes[r["participant"]] for r in rows if r["excluded_participant"] == "True"} == {"p3"}
    assert [codes[r["participant"]] for r in rows if r["discarded_early"] == "True"] == ["p4"]


def independent_means() -> dict[str, tuple[int, float, float | None]]:
    """(n, mean, CI half-width) per system over ratings neither excluded nor early."""
    values: dict[str, list[int]] = {}
    for participant, ratings in RATINGS.items():
        if participant == "p3":
            continue
        for system, _, value, early in ratings:
            if not early:
                values.setdefault(system, []).append(value)
    result = {}
    for system, xs in values.items():
        n, mean = len(xs), sum(xs) / len(xs)
        half = None
        if n >= 2:
            sd = math.sqrt(sum((x - mean) ** 2 for x in xs) / (n - 1))
            half = stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)
        result[system] = (n, mean, half)
    return result


def test_the_monitor_counts_participants_and_ratings_and_its_means_match_scipy(client, study):
    monitor = study_monitor(study)
    assert (monitor.participants_started, monitor.participants_finished, monitor.participants_excluded) == (5, 4, 1)
    assert monitor.participants_early == 2  # p4 flagged, p5 refused
    assert (monitor.ratings_collected, monitor.ratings_kept) == (14, 10)
    # 12 clips: MoGlow control-1 has two ratings, several have none.
    assert (monitor.clips, monitor.per_stimulus_min, monitor.per_stimulus_max) == (12, 0, 2)
    expected = independent_means()
    assert {m.system for m in monitor.means} == {"MoGlow", "RNN", "NAT", "BAD"}
    for row in monitor.means:
        n, mean, half = expected[row.system]
        assert row.n == n and row.mean == pytest.approx(mean)
        if half is None:
            assert row.ci_low is None and n == 1  # RNN: one rating has no interval
        else:
            assert row.ci_half == pytest.approx(half) and row.ci_low == pytest.approx(mean - half)

    page = client.get(f"/studies/{study.pk}/monitor/").content.decode()
    moglow = expected["MoGlow"]
    assert f"{moglow[1]:.3f}" in page and f"± {moglow[2]:.3f}" in page and "needs two ratings" in page
    assert f"/p/{study.key}/?PROLIFIC_PID={{{{%PROLIFIC_PID%}}}}" in page
    assert '<td id="failed-checks">1 (20 %)</td>' in page and '<td id="answered-early">2 (40 %)</td>' in page


def test_means_update_as_ratings_arrive(client, study):
    before = {m.system: m for m in study_monitor(study).means}
    participant = Participant.objects.create(study=study, platform_id="p6")
    stimulus = Stimulus.objects.get(study=study, system__name="RNN", control__name="control-1")
    Rating.objects.create(assignment=Assignment.objects.create(participant=participant, stimulus=stimulus, position=0),
                          value=4)
    page = client.get(f"/studies/{study.pk}/monitor/").content.decode()
    assert before["RNN"].ci_low is None
    xs = [2, 4]
    half = stats.t.ppf(0.975, 1) * stats.tstd(xs) / math.sqrt(2)
    assert "3.000" in page and f"± {half:.3f}" in page


def test_open_close_and_the_analysis_report(client, study):
    study.is_open = False
    study.save()
    assert client.post(f"/studies/{study.pk}/open/", {"open": "1"}).status_code == 302
    study.refresh_from_db()
    assert study.is_open
    response = client.post(f"/studies/{study.pk}/report/")
    assert response.status_code == 302 and response["Location"].startswith("/analysis/")
    report = client.get(response["Location"]).content.decode()
    assert "Mean ratings ± 95 % CI" in report and "MoGlow" in report
    client.post(f"/studies/{study.pk}/open/", {"open": "0"})
    study.refresh_from_db()
    assert not study.is_open


def test_a_get_of_the_report_address_leads_to_the_monitors_report_button_and_the_report_back_to_its_study(
        client, study):
    response = client.get(f"/studies/{study.pk}/report/")
    assert response.status_code == 302 and response["Location"] == f"/studies/{study.pk}/monitor/#data"
    monitor = client.get(response["Location"]).content.decode()
    assert "press “Analysis report”" in monitor and '<section id="data">' in monitor
    report = client.get(client.post(f"/studies/{study.pk}/report/")["Location"]).content.decode()
    assert f'<a href="/studies/{study.pk}/monitor/">← {study.title}: back to its monitor</a>' in report
    table = io.BytesIO(client.get(f"/studies/{study.pk}/ratings.csv").content)
    table.name = "ratings.csv"
    uploaded = client.post("/analysis/", {"ratings": table})
    assert "back to its monitor" not in client.get(uploaded["Location"]).content.decode()  # an upload has no study


def test_the_monitor_says_too_few_ratings_instead_of_fitting_models_and_marks_intervals_from_few_participants(
        client, study):
    monitor = study_monitor(study)
    assert not any("mixed model" in title for title, _ in monitor.tables)
    assert any("too few ratings: " in note and "from 3 participants" in note
               and f"a model needs at least {MODEL_MIN_PARTICIPANTS} participants" in note
               for note in monitor.analysis_notes)
    moglow = next(row for row in monitor.means if row.system == "MoGlow")
    assert moglow.participants == 2 and moglow.warning.startswith("from 2 participants only")
    page = client.get(f"/studies/{study.pk}/monitor/").content.decode()
    assert "‡ from 2 participants only" in page and 'id="few-participants"' in page
    assert f"fewer than {INTERVAL_FEW_PARTICIPANTS} participants" in page
