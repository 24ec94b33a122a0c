"""The plan locked when a study opens (pre-registration) and the deviations recorded after.

Opening freezes the plan as canonical JSON with its SHA-256; reopening keeps it; a
change after opening (a threshold, a system removed, participants past the plan) is
listed on the plan page and in the analysis report, while changes before opening are
none; a study never opened has no plan, and its report says so.
"""

from __future__ import annotations

import hashlib
import json

import pytest
from django.utils import timezone

from studyapp.models import ControlSignal, ImmutableRow, Participant, PlanDeviation, StudyPlan, System
from studyapp.participants.assignment import StudyFull, enrol
from studyapp.preregistration.contents import canonical_json
from studyapp.preregistration.lock import build_plan, deviations, preregistration, restore_preregistration
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import make_study
from tests.test_study_monitor import store_ratings


@pytest.fixture
def closed_study(client, db, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    study = make_study(controls=3, is_open=False)
    client.force_login(study.owner)
    return study


def open_it(client, study, open_: bool = True) -> None:
    response = client.post(f"/studies/{study.pk}/open/", {"open": "1" if open_ else "0"})
    assert response.status_code == 302
    study.refresh_from_db()
    assert study.is_open == open_


def settings_form(study, **changes) -> dict:
    """The study form's fields as its page posts them, with ``changes``."""
    from studyapp.researchers.setup.forms import StudyForm
    form = StudyForm(instance=study)
    data = {name: form[name].value() for name in form.fields}
    data.update(changes)
    return {name: value for name, value in data.items() if value is not None and value is not False}


def report_of(client, study) -> tuple[str, dict, str]:
    """The study's analysis report: its page, its plan.json and its plan.md."""
    from django.conf import settings
    response = client.post(f"/studies/{study.pk}/report/")
    assert response.status_code == 302 and response["Location"].startswith("/analysis/")
    digest = response["Location"].rstrip("/").rsplit("/", 1)[1]
    folder = settings.MEDIA_ROOT / "reports" / digest
    page = client.get(response["Location"]).content.decode()
    return page, json.loads((folder / "plan.json").read_text()), (folder / "plan.md").read_text()


def test_opening_locks_the_plan_as_canonical_json_with_its_sha256(client, closed_study):
    study = closed_study
    assert not StudyPlan.objects.filter(study=study).exists()
    open_it(client, study)
    plan = StudyPlan.objects.get(study=study)
    data = json.loads(plan.canonical)
    # canonical: sorted keys, no spaces, and the hash is of exactly those bytes
    assert plan.canonical == json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    assert plan.sha256 == hashlib.sha256(plan.canonical.encode()).hexdigest()
    assert data["design"]["name"] == "single" and data["design"]["settings"]["ratings_per_stimulus"] == 3
    assert data["rules"]["bad_at_or_above"] == 4.0 and data["rules"]["natural_below"] == 2.0
    assert set(data["systems"]) == {"MoGlow", "RNN", "NAT", "BAD"}
    assert set(data["controls"]) == {"control-0", "control-1", "control-2"}
    assert any("Tukey" in test for test in data["analysis"]["tests"])
    # 9 rated clips x 3 ratings; each participant rates 5 besides the BAD check, NAT checks counting
    assert data["participants"]["source"] == "targets" and 27 / 6 <= data["participants"]["planned"] <= 27 / 4
    # the same study gives the same plan, byte for byte: the hash is stable
    assert canonical_json(build_plan(study)) == plan.canonical
    # closing and opening again keeps the plan locked at first
    open_it(client, study, False)
    open_it(client, study)
    again = StudyPlan.objects.get(study=study)
    assert (again.pk, again.sha256, again.locked_at) == (plan.pk, plan.sha256, plan.locked_at)
    assert deviations(study) == []
    with pytest.raises(ImmutableRow):
        again.save()


def test_the_expected_effect_plans_the_participants_by_the_power_of_the_designs_test(client, closed_study):
    study = closed_study
    response = client.post(f"/studies/{study.pk}/", settings_form(study, expected_effect="0.5"))
    assert response.status_code == 302
    open_it(client, study)
    section = json.loads(StudyPlan.objects.get(study=study).canonical)["participants"]
    # three compared systems (MoGlow, RNN, NAT), three pairs: 2 (z_{1-0.05/6} + z_0.8)^2 / 0.5^2 = 83.8
    assert section["source"] == "power" and section["units"] == 84 and section["compared_systems"] == 3
    assert section["planned"] == -(-84 // section["units_per_participant"])
    page = client.get(f"/studies/{study.pk}/plan/").content.decode()
    assert f"{section['planned']} participants, from the power of the design" in page


def test_an_expected_effect_outside_the_designs_terms_is_refused_on_the_settings_page(client, closed_study):
    response = client.post(f"/studies/{closed_study.pk}/", settings_form(closed_study, design="pairwise",
                                                                        expected_effect="0.4"))
    assert response.status_code == 400
    assert "must lie above 0.5" in response.content.decode()


def test_changes_before_opening_are_no_deviation(client, closed_study):
    study = closed_study
    study.bad_threshold = 3.0
    study.save()
    System.objects.get(study=study, name="RNN").delete()
    open_it(client, study)
    assert deviations(study) == []
    assert json.loads(StudyPlan.objects.get(study=study).canonical)["rules"]["bad_at_or_above"] == 3.0


def test_a_threshold_changed_after_opening_appears_in_the_reports_deviations(client, closed_study):
    study = closed_study
    open_it(client, study)
    response = client.post(f"/studies/{study.pk}/", settings_form(study, bad_threshold="3.5"))
    assert response.status_code == 302
    store_ratings(study)
    page, plan_json, plan_md = report_of(client, study)
    locked = StudyPlan.objects.get(study=study)
    assert [(row["field"], row["old"], row["new"]) for row in plan_json["deviations"]] == [
        ("rule.bad_at_or_above", 4.0, 3.5)]
    assert plan_json["sha256"] == locked.sha256
    assert locked.sha256 in page and "rule bad_at_or_above: 4 → 3.5" in page
    assert locked.sha256 in plan_md and "rule bad_at_or_above: 4 → 3.5" in plan_md
    # the same change seen again is not a second deviation
    study.refresh_from_db()
    study.save()
    assert PlanDeviation.objects.filter(study=study).count() == 1


def test_a_removed_system_an_added_control_and_participants_past_the_plan_are_deviations(client, closed_study):
    study = closed_study
    open_it(client, study)
    rnn = System.objects.get(study=study, name="RNN")
    assert client.post(f"/studies/{study.pk}/systems/{rnn.pk}/remove/").status_code == 302
    assert not System.objects.filter(pk=rnn.pk).exists()
    ControlSignal.objects.create(study=study, name="walk-extra", origin=ControlSignal.Origin.SYNTHETIC,
                                 control={"type": "path"}, seconds=4.0)
    planned = json.loads(StudyPlan.objects.get(study=study).canonical)["participants"]["planned"]
    now = timezone.now()
    for index in range(planned + 2):
        Participant.objects.create(study=study, platform_id=f"p{index}", finished_at=now)
    Participant.objects.create(study=study, platform_id="screened", finished_at=now, screened_out_at=now)
    rows = deviations(study)
    assert [row["field"] for row in rows] == ["system.RNN", "control.walk-extra", "participants"]
    assert rows[1]["old"] is None and rows[1]["new"]["origin"] == ControlSignal.Origin.SYNTHETIC
    assert rows[0]["new"] is None and rows[0]["old"]["role"] == System.Role.MODEL
    assert (rows[2]["old"], rows[2]["new"], rows[2]["recorded"]) == (planned, planned + 2, False)
    page = client.get(f"/studies/{study.pk}/plan/").content.decode()
    assert "system RNN removed" in page and "control walk-extra added" in page
    assert f"{planned + 2} participants finished where the plan counted on {planned}" in page


def test_a_study_never_opened_has_no_plan_and_its_report_says_so(client, closed_study):
    study = closed_study
    store_ratings(study)
    assert preregistration(study) == {"locked": False, "deviations": []}
    page, plan_json, plan_md = report_of(client, study)
    assert plan_json == {"locked": False, "deviations": []}
    assert "never opened: no plan was locked" in page and "never opened: no plan was locked" in plan_md
    assert "never opened" in client.get(f"/studies/{study.pk}/plan/").content.decode()


def test_the_plan_page_is_its_owners_only(client, closed_study):
    from django.contrib.auth.models import User
    client.force_login(User.objects.create(username="someone-else"))
    assert client.get(f"/studies/{closed_study.pk}/plan/").status_code == 404
    client.logout()
    assert client.get(f"/studies/{closed_study.pk}/plan/").status_code == 302  # to the login page


def test_a_plan_restored_elsewhere_keeps_its_hash_and_deviations_and_refuses_a_changed_plan(client, closed_study):
    study = closed_study
    open_it(client, study)
    study.natural_threshold = 1.5
    study.save()
    data = preregistration(study)
    copy = make_study(owner_name="elsewhere", controls=3, is_open=False)
    tampered = {**data, "plan": {**data["plan"], "design": {**data["plan"]["design"], "name": "pairwise"}}}
    with pytest.raises(ValueError, match="does not match its SHA-256"):
        restore_preregistration(copy, tampered)
    restore_preregistration(copy, data)
    assert preregistration(copy) == data


@pytest.mark.parametrize("make, fields", [
    (make_study, {"design": "single"}), (make_study, {"design": "side-by-side", "scale_min": 0, "scale_max": 100}),
    (make_study, {"design": "pairwise", "pages_per_participant": 4}),
    (make_appropriateness_study, {"ratings_per_stimulus": 2})], ids=["single", "side-by-side", "pairwise",
                                                                    "appropriateness"])
def test_the_targets_planned_participants_are_those_enrolment_admits(db, settings, tmp_path, make, fields):
    settings.MEDIA_ROOT = tmp_path
    study = make(**fields)
    section = json.loads(StudyPlan.objects.get(study=study).canonical)["participants"]
    admitted = 0
    with pytest.raises(StudyFull):
        while True:  # each holds their pages, as one who answers them all would
            enrol(study, f"p{admitted}", {})
            admitted += 1
    assert section["source"] == "targets" and section["planned"] == admitted > 0


def test_the_plan_page_says_the_camera_in_words_not_as_json(client, closed_study):
    study = closed_study
    open_it(client, study)
    page = client.get(f"/studies/{study.pk}/plan/").content.decode()
    line = next(line for line in page.splitlines() if "Camera" in line)
    assert "35° round the vertical and 18° above the horizon" in line and "following the character" in line
    assert "{" not in line and "azimuth" not in line and "&quot;" not in line
