"""The side-by-side and pairwise designs on the participant's path: pages, answers, export."""

from __future__ import annotations

import io
import re

import pytest
from django.contrib.auth.models import User
from django.core.exceptions import ValidationError
from django.test import Client
from django.urls import reverse

from analysis.stats.minimums import MODEL_MIN_PARTICIPANTS
from analysis.ratings.schema import read_ratings
from studyapp.models import Participant, Rating, Stimulus, Study, System
from studyapp.researchers.results.export import ratings_csv
from studyapp.researchers.setup.forms import StudyForm
from tests.study_fixtures import current_page, make_study
from tests.test_study_participant import enter, make_shown_long_ago, post

pytestmark = pytest.mark.django_db

SIDE_BY_SIDE = {"design": "side-by-side", "scale_min": 0, "scale_max": 100, "pages_per_participant": 2}
PAIRWISE = {"design": "pairwise", "pages_per_participant": 4}


def watched(slots) -> dict:
    """Every clip of a page played to its end before the answer."""
    return {f"{name}-{slot}": value for slot in slots
            for name, value in (("started_s", 0.1), ("ended_s", 4.2), ("answered_s", 9.0), ("played_until_s", 4.0))}


def through_practice(client: Client, study: Study, pid: str = "pid-1") -> Participant:
    enter(client, study, pid)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    participant = Participant.objects.get(study=study, platform_id=pid)
    for index in range(len(participant.training)):
        post(client, study, "practice", index=index)
    return participant


def page_html(client: Client, study: Study) -> str:
    return client.get(reverse("participant-page", args=[study.key])).content.decode()


def page_token(html: str) -> str:
    return re.search(r'name="page" value="([0-9a-f]+)"', html).group(1)


def moved(slots) -> dict:
    """What the page's script sends of sliders the participant has moved."""
    return {f"moved-{slot}": "1" for slot in slots}


def rate_page(client: Client, study: Study, participant: Participant, value_of=lambda a: 50, **extra):
    """Answer the side-by-side page on screen (every slider moved); ``value_of(assignment)`` gives each slider's value."""
    html = page_html(client, study)
    page = current_page(participant)
    make_shown_long_ago(participant)
    values = {f"value-{a.slot}": value_of(a) for a in page} | moved(a.slot for a in page)
    return post(client, study, "rate", page=page_token(html), **{**values, **watched(a.slot for a in page), **extra})


def compare(client: Client, study: Study, participant: Participant, answer: str = "left", **extra):
    html = page_html(client, study)
    make_shown_long_ago(participant)
    return post(client, study, "rate", page=page_token(html), answer=answer, **{**watched((1, 2)), **extra})


def test_a_side_by_side_page_shows_every_system_of_one_control_under_neutral_labels():
    study = make_study(**SIDE_BY_SIDE, bad_checks=2)
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    page = current_page(participant)
    assert {a.stimulus.system.name for a in page} == {"MoGlow", "RNN", "NAT", "BAD"}  # BAD as the anchor
    assert len({a.stimulus.control_id for a in page}) == 1
    assert [a.slot for a in page] == [1, 2, 3, 4]
    for a in page:
        assert f'src="{a.stimulus.video_url}"' in html
    assert re.findall(r"<h2>Clip (\w)\b", html) == ["A", "B", "C", "D"]
    assert html.count('type="range"') == 4 and 'min="0" max="100"' in html
    for system in System.objects.filter(study=study):
        assert not re.search(rf"\b{re.escape(system.name)}\b", html), system.name
    assert "control-" not in html


@pytest.mark.parametrize("settings, answer_field", [(SIDE_BY_SIDE, 'type="range"'), (PAIRWISE, 'name="answer"')])
def test_practice_shows_the_designs_own_page_locked_until_played_and_records_nothing(settings, answer_field):
    study = make_study(**settings, controls=4, training_clips=3, bad_checks=0)
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    participant = Participant.objects.get(study=study)
    practice = Stimulus.objects.filter(pk__in=participant.training)
    rated = {a.stimulus.control_id for a in participant.assignments.select_related("stimulus")}
    pages = 0
    while (participant := Participant.objects.get(pk=participant.pk)).training_done < len(participant.training):
        html = page_html(client, study)
        assert "Practice page" in html and "(not recorded)" in html and answer_field in html
        assert re.search(r'<button type="submit"[^>]* disabled', html)  # until every clip has played
        assert re.findall(r"<h2>Clip (\w)\b", html)[:2] == ["A", "B"]
        assert post(client, study, "practice", index=participant.training_done, answer="left",
                    **{"value-1": 50}).status_code == 302
        pages += 1
    # About training_clips clips in whole pages, none of a control (side by side) the participant rates.
    assert pages == (1 if settings is SIDE_BY_SIDE else 2) and not Rating.objects.exists()
    if settings is SIDE_BY_SIDE:
        assert not {s.control_id for s in practice} & rated and practice.count() >= study.training_clips
    assert "Practice" not in page_html(client, study)  # the rated pages follow


def test_side_by_side_answers_are_stored_per_clip_and_export_in_the_schema():
    study = make_study(**SIDE_BY_SIDE, bad_checks=1)
    client = Client()
    participant = through_practice(client, study)
    seen = []
    for _ in range(study.pages_per_participant):
        seen.append(current_page(participant))
        assert rate_page(client, study, participant, lambda a: 10 * a.slot).status_code == 302
    assert "C0MPL3TE" in page_html(client, study)
    ratings = Rating.objects.filter(assignment__participant=participant)
    assert sorted(r.value for r in ratings) == sorted(10 * a.slot for page in seen for a in page)

    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert set(table["design"]) == {"side-by-side"}
    assert len(table) == sum(len(page) for page in seen)
    first = table[table["page"] == table["page"].iloc[0]]
    assert sorted(first["position"]) == list(range(1, len(first) + 1))
    assert (first["value"] == 10 * first["position"]).all()
    assert set(table["scale_min"]) == {0} and set(table["scale_max"]) == {100}


def test_a_side_by_side_page_without_every_rating_or_off_the_scale_is_refused_and_stores_nothing():
    study = make_study(**SIDE_BY_SIDE)
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    make_shown_long_ago(participant)
    missing = post(client, study, "rate", page=page_token(html), **{"value-1": 50}, **watched((1,)))
    assert missing.status_code == 400 and "needs a rating" in missing.content.decode()
    values = {f"value-{slot}": 50 for slot in (1, 2, 3)}
    off = post(client, study, "rate", page=page_token(html), **{**values, "value-2": 101}, **watched((1, 2, 3)))
    assert off.status_code == 400 and "outside the scale" in off.content.decode()
    assert post(client, study, "rate", assignment=page_token(html), value=3).status_code == 403  # names no page
    assert not Rating.objects.exists()


def test_an_untouched_slider_is_refused_where_each_slider_must_move_and_stores_nothing():
    study = make_study(**SIDE_BY_SIDE, bad_checks=0)  # three clips a page: MoGlow, RNN, NAT
    assert study.sliders_must_move  # a new study's default
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    make_shown_long_ago(participant)
    untouched = {f"value-{slot}": 50 for slot in (1, 2, 3)}  # where every slider starts
    response = post(client, study, "rate", page=page_token(html), **untouched, **moved((1, 3)), **watched((1, 2, 3)))
    assert response.status_code == 400
    assert "not moved: the slider of clip B" in response.content.decode()
    assert not Rating.objects.exists()
    # The script's word that a slider was moved (and back to the middle) is enough.
    assert post(client, study, "rate", page=page_token(html), **untouched, **moved((1, 2, 3)),
                **watched((1, 2, 3))).status_code == 302
    assert Rating.objects.count() == 3


def test_without_the_pages_script_a_value_other_than_the_start_counts_as_moved():
    study = make_study(**SIDE_BY_SIDE, bad_checks=0)  # three clips a page: MoGlow, RNN, NAT
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    make_shown_long_ago(participant)
    plain = {"value-1": 50, "value-2": 70, "value-3": 0}  # a form posted without the script: no moved-* fields
    response = post(client, study, "rate", page=page_token(html), **plain, **watched((1, 2, 3)))
    assert response.status_code == 400 and "not moved: the slider of clip A" in response.content.decode()
    plain["value-1"] = 51
    assert post(client, study, "rate", page=page_token(html), **plain, **watched((1, 2, 3))).status_code == 302


def test_untouched_sliders_are_taken_where_the_study_turns_the_rule_off():
    study = make_study(**SIDE_BY_SIDE, bad_checks=0, sliders_must_move=False)
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    make_shown_long_ago(participant)
    assert post(client, study, "rate", page=page_token(html), **{f"value-{slot}": 50 for slot in (1, 2, 3)},
                **watched((1, 2, 3))).status_code == 302
    assert 'data-sliders-must-move' not in html


def test_the_sliders_setting_is_side_by_sides_alone_and_harmless_left_on_elsewhere():
    assert StudyForm.field_designs("sliders_must_move") == ["side-by-side"]
    single = make_study()  # left on, as a new study has it: the single design does not read it
    assert single.sliders_must_move
    single.full_clean()
    side = make_study(owner_name="other", **SIDE_BY_SIDE)
    assert 'data-sliders-must-move' in _first_rated_page(side)


def test_the_new_study_form_shows_the_sliders_setting_for_side_by_side_ticked(client):
    client.force_login(User.objects.create_user("researcher"))
    html = client.get(reverse("study-create")).content.decode()
    row = re.search(r'<div class="field check" data-designs="([^"]*)"[^>]*>\s*<label for="id_sliders_must_move">'
                    r'Each slider must be moved before answering</label>\s*<div class="input">(<input[^>]*>)', html)
    assert row and row.group(1) == "side-by-side" and "checked" in row.group(2)


def _first_rated_page(study: Study) -> str:
    client = Client()
    through_practice(client, study)
    return page_html(client, study)


@pytest.mark.parametrize("settings", [SIDE_BY_SIDE, PAIRWISE])
def test_a_page_answered_sooner_than_its_clips_last_is_refused_with_409_and_counted(settings):
    from studyapp.researchers.results.monitor import study_monitor

    study = make_study(**settings, bad_checks=0)  # the full-play rule is on by default
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)  # the server has just sent the page: its 4 s clips cannot have played
    page = current_page(participant)
    answer = {f"value-{a.slot}": 50 for a in page} | moved(a.slot for a in page) if settings is SIDE_BY_SIDE \
        else {"answer": "left"}
    answer.update(watched(a.slot for a in page))  # whatever the browser claims
    response = post(client, study, "rate", page=page_token(html), **answer)
    assert response.status_code == 409 and "Please watch every clip to its end" in response.content.decode()
    assert not Rating.objects.exists() and current_page(participant) == page
    assert Participant.objects.get(pk=participant.pk).refused_early == 1
    assert study_monitor(study).participants_early == 1
    make_shown_long_ago(participant)
    assert post(client, study, "rate", page=page_token(html), **answer).status_code == 302
    assert not Rating.objects.filter(answered_before_end=True).exists()


def test_a_pairwise_page_shows_two_systems_of_one_control_and_stores_the_answer_on_both():
    study = make_study(**PAIRWISE, bad_checks=0, preference_strengths=3)
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    page = current_page(participant)
    assert [a.slot for a in page] == [1, 2] and len({a.stimulus.control_id for a in page}) == 1
    assert page[0].stimulus.system_id != page[1].stimulus.system_id
    assert "A is better" in html and "No preference" in html and html.count('name="strength"') == 3
    for system in System.objects.filter(study=study):
        assert not re.search(rf"\b{re.escape(system.name)}\b", html), system.name

    assert compare(client, study, participant, "left").status_code == 400  # a preference needs its strength
    assert compare(client, study, participant, "none", strength=2).status_code == 400
    assert compare(client, study, participant, "sideways").status_code == 400
    assert not Rating.objects.exists()
    assert compare(client, study, participant, "right", strength=2).status_code == 302
    stored = Rating.objects.filter(assignment__in=page)
    assert [(r.answer, r.strength, r.value) for r in stored] == [("right", 2, None)] * 2

    while compare(client, study, participant, "none").status_code == 302 and current_page(participant):
        pass
    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert set(table["design"]) == {"pairwise"} and "value" not in table.columns
    assert len(table) == 2 * study.pages_per_participant
    assert table.groupby("page")["side"].apply(sorted).tolist() == [["left", "right"]] * study.pages_per_participant


def test_a_study_asking_three_degrees_of_preference_reports_its_leaderboard_with_the_stated_weights(settings, tmp_path):
    from tests.test_study_rules import in_app_report

    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(**PAIRWISE, controls=3, bad_checks=0, training_clips=0, preference_strengths=3)
    answers = [("left", 3), ("none", None), ("right", 1), ("left", 2)]  # every degree, and ties: a fit exists
    for n in range(4):
        client = Client()
        participant = through_practice(client, study, f"pid-{n}")
        for answer, strength in answers:
            assert compare(client, study, participant, answer,
                           **({"strength": strength} if strength else {})).status_code == 302
    researcher = Client()
    researcher.force_login(study.owner)
    folder = in_app_report(researcher, study, settings)
    board = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert set(board["strength"].dropna()) == {1, 2, 3}
    assert (folder / "tables" / "leaderboard.csv").is_file() and (folder / "figures" / "win_fraction.png").is_file()
    page = researcher.get(f"/analysis/{folder.name}/").content.decode()
    assert "a preference of strength k counts 2k wins of the preferred system" in page


def test_the_design_is_fixed_once_participants_start_and_side_by_side_rates_on_0_to_100():
    study = make_study()
    shown = StudyForm(instance=study)
    camera = {name: shown.fields[name].initial for name in shown.camera_fields() if shown.fields[name].initial is not None}
    form = StudyForm({**shown.initial, **camera, "design": "side-by-side",
                      "scale_min": study.scale_min, "scale_max": study.scale_max}, instance=study)
    assert form.is_valid(), form.errors
    assert (form.cleaned_data["scale_min"], form.cleaned_data["scale_max"]) == (0, 100)
    Participant.objects.create(study=study, platform_id="p1")
    fixed = StudyForm(instance=study)
    assert fixed.fields["design"].disabled and fixed.fields["preference_strengths"].disabled


def answer_everything(study: Study, pids: list[str], value_of=None) -> None:
    for pid in pids:
        client = Client()
        participant = through_practice(client, study, pid)
        while current_page(participant):
            if study.design == "side-by-side":
                rate_page(client, study, participant, value_of)
            else:  # the left clip, or the other one where it is BAD (an attention check)
                bad_left = current_page(participant)[0].stimulus.system.role == System.Role.BAD
                compare(client, study, participant, "right" if bad_left else "left")


def test_the_monitor_summarises_each_design_with_the_analysis_functions():
    from studyapp.researchers.results.monitor import study_monitor

    sbs = make_study(**SIDE_BY_SIDE, bad_checks=0, ratings_per_stimulus=10)
    by_system = {"MoGlow": 60, "RNN": 40, "NAT": 90}
    answer_everything(sbs, ["a", "b", "c"], lambda a: by_system[a.stimulus.system.name])
    monitor = study_monitor(sbs)
    titles = [title for title, _ in monitor.tables]
    assert titles[0] == "Median and mean per system (95 % CIs)"
    assert titles[-1] == "How many more ratings give 80 % power per pair (at alpha 0.05)"
    # three participants are too few for the crossed model: the monitor says so instead of fitting it
    assert not any("Crossed linear mixed model" in t or "Cumulative link" in t for t in titles)
    assert any(note.startswith("No rater- and clip-aware models for ") and "too few ratings: 18 from 3 participants"
               in note and f"at least {MODEL_MIN_PARTICIPANTS} participants" in note for note in monitor.analysis_notes)
    summary = monitor.tables[0][1]
    for system, value in by_system.items():  # n = 3 participants x 2 pages; median = mean = the value given
        assert re.search(rf"<td>{system}</td>\s*<td>6</td>\s*<td>{value}</td>(\s*<td>{value}</td>){{3}}", summary)

    pairwise = make_study(**PAIRWISE, bad_checks=1, ratings_per_stimulus=10)
    answer_everything(pairwise, ["a", "b"])
    monitor = study_monitor(pairwise)
    assert [title for title, _ in monitor.tables] == [
        "Preference per pair (Wilson 95 % CI, sign test, Holm)",
        "How many more ratings give 80 % power per pair (at alpha 0.05)"]
    assert "BAD" not in monitor.tables[0][1] and monitor.means == []
    assert not Participant.objects.filter(study=pairwise, excluded=True).exists()


def test_the_demo_opens_a_side_by_side_study_on_the_single_studys_clips(settings, tmp_path):
    from studyapp.participants.assignment import enrol
    from studyapp.demo import ensure_side_by_side_study

    settings.MEDIA_ROOT = tmp_path / "media"
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"a rendered clip")
    single = make_study(video=video)
    side_by_side = ensure_side_by_side_study(single)
    assert (side_by_side.design, side_by_side.scale_min, side_by_side.scale_max) == ("side-by-side", 0, 100)
    assert side_by_side.is_open and side_by_side.owner == single.owner
    clips = list(side_by_side.stimuli.all())
    assert sorted(s.content_key for s in clips) == sorted(single.stimuli.values_list("content_key", flat=True))
    assert not {s.token for s in clips} & set(single.stimuli.values_list("token", flat=True))
    assert all(s.video_path().read_bytes() == b"a rendered clip" for s in clips)
    assert ensure_side_by_side_study(single).pk == side_by_side.pk and side_by_side.stimuli.count() == len(clips)
    participant = enrol(side_by_side, "p1", {})
    assert len(current_page(participant)) >= 3


def test_create_study_takes_the_design_and_side_by_side_rates_on_0_to_100():
    from io import StringIO

    from django.contrib.auth.models import User
    from django.core.management import call_command

    User.objects.create(username="r")
    out = StringIO()
    call_command("create_study", "r", "Sliders", "--design", "side-by-side", "--pages", "5", stdout=out)
    study = Study.objects.get(pk=int(out.getvalue()))
    assert (study.design, study.scale_min, study.scale_max, study.pages_per_participant) == ("side-by-side", 0, 100, 5)


def test_made_up_clips_and_numbers_in_a_page_form_are_refused_with_a_message():
    study = make_study(**SIDE_BY_SIDE)
    client = Client()
    participant = through_practice(client, study)
    token = page_token(page_html(client, study))
    values = {f"value-{slot}": 50 for slot in (1, 2, 3)} | moved((1, 2, 3))
    for extra in ({"value-99999999999": 50}, {"value-2": "fifty"}, {"started_s-1": "soon"}):
        response = post(client, study, "rate", page=token, **{**values, **watched((1, 2, 3)), **extra})
        assert response.status_code == 400, extra
    assert post(client, study, "rate", page="f" * 32, **values).status_code == 403
    assert not Rating.objects.exists() and current_page(participant)


def test_abx_pages_pair_the_models_under_the_controls_natural_clip_as_reference_x():
    study = make_study(**PAIRWISE, abx=True, bad_checks=1)
    client = Client()
    participant = through_practice(client, study)
    while current_page(participant):
        page = current_page(participant)
        html = page_html(client, study)
        natural = study.stimuli.get(control=page[0].stimulus.control, system__role=System.Role.NATURAL)
        assert 'data-slot="x"' in html and f'src="{natural.video_url}"' in html and "closer to the reference X" in html
        roles = sorted(a.stimulus.system.role for a in page)
        assert roles in (["model", "model"], ["bad", "natural"])  # NAT is X, so it is paired only in the check
        assert compare(client, study, participant, "left").status_code == 302
    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert table.groupby("page").size().eq(2).all()  # X is not a row: the pairwise schema as it is

    single = make_study(owner_name="other")
    single.abx = True
    with pytest.raises(ValidationError):
        single.full_clean()
