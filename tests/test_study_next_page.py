"""A page of clips answered with one request: the answer's response is the next page.

The clip pages' script sends each answer with the ``Studyapp-Next-Page: in-place``
header; where the next page is another page of clips the response is that page, marked
shown as the answer is stored (the full-play rule reads the server's clock from there),
and where it is not (the end, closing questions, a session stopped by failed checks) the
response is the redirect every form gets. Without the header (no script) nothing changes.
"""

from __future__ import annotations

import re

import pytest
from django.db import connection
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Question, Rating, Study
from studyapp.participants.path import NEXT_PAGE_HEADER
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import current_page, make_study
from tests.test_study_participant import WATCHED, enter, make_shown_long_ago, post

pytestmark = pytest.mark.django_db

IN_PLACE = {"headers": {NEXT_PAGE_HEADER: "in-place"}}
DESIGNS = {
    "single": {},
    "side-by-side": {"design": "side-by-side", "scale_min": 0, "scale_max": 100, "pages_per_participant": 3},
    "pairwise": {"design": "pairwise", "pages_per_participant": 3},
    "pairwise graded": {"design": "pairwise", "pages_per_participant": 3, "preference_strengths": 3},
    "appropriateness": {"design": "appropriateness", "pages_per_participant": 3},
}


def study_of(design: str, **fields) -> Study:
    settings = {**DESIGNS[design], **fields}
    if settings.get("design") == "appropriateness":
        return make_appropriateness_study(**settings)
    return make_study(controls=3, **settings)


def answer(study: Study, participant: Participant) -> dict:
    """A valid answer to the page on screen, every clip watched to its end (and the
    instructed check followed, where the page is one)."""
    clips = current_page(participant)
    form = {"value": 3, **WATCHED} if study.design == "single" else {
        f"{name}-{clip.slot}": value for clip in clips for name, value in WATCHED.items()}
    if study.design == "side-by-side":
        form.update({f"value-{clip.slot}": 100 if clip.expected == "max" else 50 for clip in clips})
        form.update({f"moved-{clip.slot}": "1" for clip in clips})  # each slider moved, as the study asks
    elif study.design != "single":
        form["answer"] = clips[0].expected or "left"
        if study.design == "appropriateness" or study.preference_strengths:
            form["strength"] = 1
    field = "assignment" if study.design == "single" else "page"
    return {field: clips[0].token, **form}


def rate(client: Client, study: Study, participant: Participant, in_place: bool = True, **extra):
    make_shown_long_ago(participant)
    form = answer(study, participant)
    return client.post(reverse("participant-rate", args=[study.key]), {**form, **extra}, **(IN_PLACE if in_place else {}))


def through_instructions(client: Client, study: Study) -> Participant:
    enter(client, study)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    return Participant.objects.get(study=study)


@pytest.mark.parametrize("design", DESIGNS)
def test_each_answer_is_one_request_whose_response_is_the_next_page_marked_shown_without_its_head(design):
    study = study_of(design, training_clips=0)
    client = Client()
    participant = through_instructions(client, study)
    pages = participant.assignments.values("page").distinct().count()
    for number in range(1, pages):
        response = rate(client, study, participant)
        assert response.status_code == 200, response.content.decode()[:500]
        html = response.content.decode()
        on_screen = current_page(participant)
        # The next page itself, as the page URL shows it: its clips, its form, its progress.
        assert f'value="{on_screen[0].token}"' in html and "data-next-page" in html
        assert all(clip.stimulus.video_url in html for clip in on_screen)
        assert f" {number + 1} of {pages}" in html
        assert all(clip.shown_at is not None for clip in on_screen)  # the server's clock starts with the response
        assert response["Cache-Control"].startswith("max-age=0")
        # Only what the script swaps in: the page on screen has the head and the scripts.
        assert "<title>" in html and "<main data-page-id=" in html
        assert "<head>" not in html and "<script" not in html and "stylesheet" not in html
        reloaded = client.get(reverse("participant-page", args=[study.key])).content.decode()
        assert f'value="{on_screen[0].token}"' in reloaded  # a reload shows the same page
        assert "<head>" in reloaded and "next-page.js" in reloaded  # the whole page, loaded anew
    last = rate(client, study, participant)  # the next page is the end: the redirect, to be loaded
    assert last.status_code == 302 and last["Location"] == reverse("participant-page", args=[study.key])
    assert "C0MPL3TE" in client.get(last["Location"]).content.decode()
    stored = Rating.objects.filter(assignment__participant=participant)
    assert stored.count() == participant.assignments.count() == stored.values("assignment").distinct().count()


def test_without_the_script_each_answer_is_a_post_and_a_redirect_as_before():
    study = study_of("single", training_clips=1, clips_per_participant=3)
    client = Client()
    participant = through_instructions(client, study)
    assert post(client, study, "practice", index=0, value=3).status_code == 302
    for _ in range(3):
        response = rate(client, study, participant, in_place=False)
        assert response.status_code == 302 and response["Location"] == reverse("participant-page", args=[study.key])
    assert Rating.objects.count() == 3 and Participant.objects.get(pk=participant.pk).finished_at is not None


def test_practice_pages_lead_in_place_to_the_next_practice_page_and_the_first_rating_page():
    study = study_of("single", training_clips=2, clips_per_participant=3)
    client = Client()
    participant = through_instructions(client, study)
    second = client.post(reverse("participant-practice", args=[study.key]), {"index": 0, "value": 3}, **IN_PLACE)
    assert second.status_code == 200 and re.search(r"Practice \w+ 2 of 2", second.content.decode())
    first_rating = client.post(reverse("participant-practice", args=[study.key]), {"index": 1, "value": 3}, **IN_PLACE)
    on_screen = current_page(participant)[0]
    assert first_rating.status_code == 200 and f'value="{on_screen.token}"' in first_rating.content.decode()
    assert on_screen.shown_at is not None and Rating.objects.count() == 0


def test_an_early_answer_sent_in_place_is_refused_with_409_and_the_page_stays():
    study = study_of("single", training_clips=0)
    client = Client()
    participant = through_instructions(client, study)
    client.get(reverse("participant-page", args=[study.key]))  # the page sent: the server's clock starts
    token = current_page(participant)[0].token
    response = client.post(reverse("participant-rate", args=[study.key]),
                           {"assignment": token, "value": 3, **WATCHED}, **IN_PLACE)  # just shown: 4 s not passed
    assert response.status_code == 409 and "Please watch the clip to its end" in response.content.decode()
    assert Rating.objects.count() == 0 and Participant.objects.get(pk=participant.pk).refused_early == 1
    assert current_page(participant)[0].token == token
    assert rate(client, study, participant).status_code == 200  # answered again once it has played


def test_a_session_stopped_by_failed_checks_and_closing_questions_are_reached_by_navigation():
    study = study_of("single", training_clips=0, clips_per_participant=4, instructed_checks=1,
                     stop_after_failed_checks=1)
    client = Client()
    participant = through_instructions(client, study)
    while not (check := current_page(participant)[0]).expected:
        assert rate(client, study, participant).status_code == 200
    wrong = 1 if check.expected != "1" else 2
    stopped = rate(client, study, participant, value=wrong)
    assert stopped.status_code == 302
    assert "did not follow the instructions" in client.get(stopped["Location"]).content.decode()

    asking = study_of("single", training_clips=0, clips_per_participant=2, bad_checks=0, natural_checks=0,
                      title="with questions", owner_name="another")
    Question.objects.create(study=asking, part=Question.Part.AFTER, text="Your age?", kind=Question.Kind.NUMBER)
    client = Client()
    participant = through_instructions(client, asking)
    assert rate(client, asking, participant).status_code == 200
    last = rate(client, asking, participant)
    assert last.status_code == 302 and "Your age?" in client.get(last["Location"]).content.decode()


def test_an_answer_in_place_needs_its_csrf_token():
    study = study_of("single", training_clips=0)
    client = Client()
    participant = through_instructions(client, study)
    client.handler.enforce_csrf_checks = True  # from the rating page on, as a browser
    make_shown_long_ago(participant)
    html = client.get(reverse("participant-page", args=[study.key])).content.decode()
    token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', html).group(1)
    form = answer(study, participant)
    url = reverse("participant-rate", args=[study.key])
    assert client.post(url, form, **IN_PLACE).status_code == 403
    assert Rating.objects.count() == 0
    assert client.post(url, {**form, "csrfmiddlewaretoken": token}, **IN_PLACE).status_code == 200
    assert Rating.objects.count() == 1


def test_an_answer_in_place_costs_fewer_queries_than_the_post_and_the_page(django_assert_max_num_queries):
    study = study_of("single")
    client = Client()
    participant = through_instructions(client, study)
    for index in range(len(participant.training)):
        post(client, study, "practice", index=index, value=3)
    on_screen = current_page(participant)[0]
    make_shown_long_ago(participant)
    participant.assignments.exclude(pk=on_screen.pk).update(shown_at=None)  # the next clip not yet shown
    form = answer(study, participant)
    # The participant with the study's stamp, the page's clips locked, the rating, the next
    # clip's shown-at time (one transaction: its begin and commit, or a savepoint's pair
    # here), and the next page's clips; the participant is not read again (the POST and the
    # page it redirects to take 8).
    with django_assert_max_num_queries(7) as queries:
        response = client.post(reverse("participant-rate", args=[study.key]), form, **IN_PLACE)
    assert response.status_code == 200
    statements = [query["sql"].split()[0] for query in queries.captured_queries]
    assert statements.count("INSERT") == 1 and statements.count("UPDATE") == 1
    assert Rating.objects.filter(assignment=on_screen).count() == 1


@pytest.mark.skipif(connection.vendor != "postgresql", reason="prepared statements are PostgreSQL's")
def test_on_postgresql_the_rating_steps_statements_are_prepared_once_a_connection_has_run_them_a_few_times():
    study = study_of("single", training_clips=0, clips_per_participant=8)
    client = Client()
    participant = through_instructions(client, study)
    for _ in range(6):
        assert rate(client, study, participant).status_code == 200
    with connection.cursor() as cursor:
        cursor.execute("SELECT statement FROM pg_prepared_statements")
        prepared = [statement for (statement,) in cursor.fetchall()]
    assert any(statement.startswith('INSERT INTO "studyapp_rating"') for statement in prepared), prepared
