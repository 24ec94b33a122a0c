"""Reasons as a study setting: the list a researcher gives (the study page, the definition
file, the bundle), locked once participants start; the page's checkboxes and "Other";
what a form may send; the reasons stored with every rating of the page and exported in
GENEA's columns. The browser's side is tests/test_study_reasons_browser.py."""

from __future__ import annotations

import csv
import html
import io
import json

import pytest
from django.core.exceptions import ValidationError
from django.test import Client

from analysis.reports.reasons import read_options
from studyapp.bundles.records import record, row_values
from studyapp.bundles.writing import study_record
from studyapp.definitions import definition_yaml
from studyapp.definitions.create import create_study_from_definition
from studyapp.models import Participant, Rating, Study
from studyapp.preregistration.fixed import change_refusal
from studyapp.researchers.results.export import export_columns, ratings_csv
from studyapp.researchers.setup.forms import StudyForm
from tests.study_fixtures import current_page, make_study
from tests.test_study_designs import PAIRWISE, SIDE_BY_SIDE, compare, page_html, rate_page, through_practice

pytestmark = pytest.mark.django_db

REASONS = "Motion smoothness\nRecognisable gestures\nUnrealistic motion\nAmount of motion"


def test_the_reasons_are_a_checkbox_each_with_its_label_and_other_with_a_bounded_text_field():
    study = make_study(**PAIRWISE, bad_checks=0, reasons=REASONS, reasons_required=True)
    client = Client()
    through_practice(client, study)
    shown = page_html(client, study)
    for number, reason in enumerate(REASONS.splitlines(), start=1):
        assert (f'<label for="reason-{number}"><input type="checkbox" id="reason-{number}" name="reason" '
                f'value="{number}"> {reason}</label>') in shown
    assert '<input type="checkbox" id="reason-other" name="other" value="1"> Other</label>' in shown
    assert 'name="other_reason" maxlength="300"' in shown and "(tick at least one)" in shown
    plain = make_study(owner_name="other", **PAIRWISE, bad_checks=0)
    through_practice(client, plain, "pid-2")
    assert 'name="reason"' not in page_html(client, plain)  # no list: nothing asked


def test_a_pages_reasons_are_stored_on_its_ratings_and_exported_in_genea_columns():
    study = make_study(**PAIRWISE, bad_checks=0, reasons=REASONS)
    client = Client()
    participant = through_practice(client, study)
    assert compare(client, study, participant, "left", reason=["3", "1"], other="1",
                   other_reason="  <b>arms</b>\n too   stiff ").status_code == 302
    assert compare(client, study, participant, "none").status_code == 302  # optional: no reason is fine
    first, second = (list(Rating.objects.filter(assignment__page=page).order_by("assignment__slot"))
                     for page in sorted(set(participant.assignments.values_list("page", flat=True)))[:2])
    assert [(r.reasons, r.other_reason) for r in first] == [(["Motion smoothness", "Unrealistic motion"],
                                                             "arms too stiff")] * 2
    assert [(r.reasons, r.other_reason) for r in second] == [([], "")] * 2
    assert export_columns(study)[-2:] == ("juiceOptions", "juiceOtherReason")
    rows = list(csv.DictReader(io.StringIO(ratings_csv(study).decode())))
    by_page = {row["page"]: row for row in rows}
    assert read_options(by_page["1"]["juiceOptions"]) == ["Motion smoothness", "Unrealistic motion", "Other"]
    assert by_page["1"]["juiceOtherReason"] == "arms too stiff"
    assert (by_page["2"]["juiceOptions"], by_page["2"]["juiceOtherReason"]) == ("{}", "")
    assert "juiceOptions" not in export_columns(make_study(owner_name="b", **PAIRWISE))  # none asked: no columns


@pytest.mark.parametrize("fields, status, message", [
    ({}, 400, "please tick at least one reason"),
    ({"reason": "5"}, 400, "a reason is one of the 4 listed, by its number; not '5'"),
    ({"reason": "²"}, 400, "by its number; not '²'"),
    ({"other": "1", "other_reason": "<i></i>  "}, 400, "please say in a few words what the other reason is"),
    ({"other_reason": "x" * 301}, 400, "the other reason is at most 300 characters, not 301"),
])
def test_a_required_reason_missing_or_a_reason_the_list_lacks_is_refused_with_what_is_wrong(fields, status, message):
    study = make_study(**PAIRWISE, bad_checks=0, reasons=REASONS, reasons_required=True)
    client = Client()
    participant = through_practice(client, study)
    response = compare(client, study, participant, "left", **fields)
    assert response.status_code == status and message in html.unescape(response.content.decode())
    assert not Rating.objects.exists()
    assert compare(client, study, participant, "left", other_reason="too slow").status_code == 302  # words suffice


def test_a_study_without_reasons_refuses_them_and_side_by_side_pages_store_them_too():
    plain = make_study(**PAIRWISE, bad_checks=0)
    client = Client()
    participant = through_practice(client, plain)
    response = compare(client, plain, participant, "left", reason="1")
    assert response.status_code == 400 and "this study asks for no reasons" in html.unescape(response.content.decode())
    sliders = make_study(owner_name="sbs", **SIDE_BY_SIDE, bad_checks=0, reasons=REASONS)
    participant = through_practice(client, sliders, "pid-2")
    slots = [a.slot for a in current_page(participant)]
    assert rate_page(client, sliders, participant, reason="2").status_code == 302
    stored = Rating.objects.filter(assignment__participant=participant).order_by("assignment__slot")
    assert [r.reasons for r in stored] == [["Recognisable gestures"]] * len(slots) and len(slots) >= 3


def test_the_reasons_are_set_on_the_study_page_checked_and_locked_once_participants_start():
    study = make_study(**PAIRWISE)
    shown = StudyForm(instance=study)
    camera = {name: shown.fields[name].initial for name in shown.camera_fields() if shown.fields[name].initial is not None}
    form = StudyForm({**shown.initial, **camera, "reasons": REASONS, "reasons_required": True}, instance=study)
    assert form.is_valid(), form.errors
    form.save()
    study.refresh_from_db()
    assert study.reason_list == REASONS.splitlines() and study.reasons_required
    for bad, message in (("a\nA", "each reason once"), ("Other", '"Other" is offered'), ("x" * 81, "at most 80"),
                         ("\n".join(map(str, range(13))), "at most 12 reasons"), ("<b>x</b>", "no < or >")):
        with pytest.raises(ValidationError, match=message):
            Study(owner=study.owner, title="t", design="pairwise", reasons=bad).full_clean()
    with pytest.raises(ValidationError, match="reasons go with the side-by-side or pairwise design"):
        Study(owner=study.owner, title="t", design="single", reasons="Smooth").full_clean()
    Participant.objects.create(study=study, platform_id="p1")
    fixed = StudyForm(instance=study)
    assert fixed.fields["reasons"].disabled and fixed.fields["reasons_required"].disabled
    assert "reasons cannot change" in change_refusal(study, ["reasons"])


def test_the_reasons_travel_in_the_study_definition():
    study = make_study(controls=0, **PAIRWISE, reasons=REASONS, reasons_required=True)
    study.systems.exclude(name="NAT").delete()  # the rest a definition can make without files
    text = definition_yaml(study)
    assert "  reasons: |-\n    Motion smoothness\n    Recognisable gestures\n" in text
    again = create_study_from_definition(text, study.owner, source="study.yaml")
    assert (again.reason_list, again.reasons_required) == (study.reason_list, True)


def test_the_reasons_and_the_answers_reasons_travel_in_the_bundles_records():
    study = make_study(**PAIRWISE, bad_checks=0, reasons=REASONS, reasons_required=True)
    client = Client()
    participant = through_practice(client, study)
    assert compare(client, study, participant, "right", reason="4", other_reason="too fast").status_code == 302
    written = json.loads(json.dumps(study_record(study)))  # as the bundle's study.json holds it
    assert row_values(Study, written["study"], "study")["reasons"] == REASONS
    assert row_values(Study, written["study"], "study")["reasons_required"] is True
    rating = json.loads(json.dumps(record(Rating.objects.first())))
    assert {k: v for k, v in row_values(Rating, rating, "rating").items() if "reason" in k} == {
        "reasons": ["Amount of motion"], "other_reason": "too fast"}
