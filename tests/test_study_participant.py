"""The participant's side of a study: entry, consent, practice, rating, exclusions, refusals."""

from __future__ import annotations

import random
import re
from collections import Counter
from datetime import timedelta

import pytest
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from studyapp.designs.rules import StudyRules
from studyapp.designs.single_pages import stimulus_loads
from studyapp.models import Assignment, Participant, Rating, Stimulus, Study, System
from studyapp.participants.assignment import StudyFull, enrol
from studyapp.researchers.results.export import ratings_rows
from tests.study_fixtures import current_clip, make_study

pytestmark = pytest.mark.django_db


def enter(client: Client, study: Study, pid: str = "pid-1"):
    return client.get(reverse("participant-enter", args=[study.key]), {"PROLIFIC_PID": pid, "STUDY_ID": "s",
                                                                       "SESSION_ID": "x"}, follow=True)


def post(client: Client, study: Study, step: str, **data):
    return client.post(reverse(f"participant-{step}", args=[study.key]), data)


def through_practice(client: Client, study: Study, pid: str = "pid-1") -> Participant:
    enter(client, study, pid)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    participant = Participant.objects.get(study=study, platform_id=pid)
    for index in range(len(participant.training)):
        post(client, study, "practice", index=index, value=3)
    return participant


def on_screen_token(client: Client, study: Study) -> str:
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    return re.search(r'name="assignment" value="([0-9a-f]+)"', page).group(1)


def make_shown_long_ago(participant: Participant) -> None:
    """As if every clip had been on screen for a minute, so no answer is early by the server's clock."""
    participant.assignments.update(shown_at=timezone.now() - timedelta(minutes=1))


WATCHED = {"started_s": 0.1, "ended_s": 4.2, "answered_s": 5.0, "played_until_s": 4.0}


def rate_current(client: Client, study: Study, participant: Participant, value: int, **times):
    token = on_screen_token(client, study)
    make_shown_long_ago(participant)
    return post(client, study, "rate", assignment=token, value=value, **{**WATCHED, **times})


def test_a_participant_goes_from_entry_link_to_completion_code():
    study = make_study(platform=Study.Platform.PROLIFIC)
    client = Client()
    first = enter(client, study)
    assert "Consent" in first.content.decode()
    participant = through_practice(client, study)
    assert Rating.objects.count() == 0  # practice answers are not recorded
    for _ in range(study.clips_per_participant):
        response = rate_current(client, study, participant, 3)
        assert response.status_code == 302
    done = client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert "C0MPL3TE" in done and "app.prolific.com/submissions/complete?cc=C0MPL3TE" in done
    participant.refresh_from_db()
    assert participant.finished_at is not None and not participant.excluded
    assert Rating.objects.filter(assignment__participant=participant).count() == study.clips_per_participant


def test_a_reload_shows_the_same_clip_and_the_same_id_cannot_start_twice():
    study = make_study()
    client = Client()
    participant = through_practice(client, study)
    assert on_screen_token(client, study) == on_screen_token(client, study)
    other_browser = Client()
    enter(other_browser, study)  # same platform id, another browser: resumes, no second participant
    assert Participant.objects.filter(study=study).count() == 1
    assert on_screen_token(other_browser, study) == on_screen_token(client, study)
    assert participant.assignments.count() == study.clips_per_participant


def test_assignment_has_checks_at_random_positions_and_each_clip_once():
    study = make_study(controls=6, clips_per_participant=8, bad_checks=1, natural_checks=1, ratings_per_stimulus=100)
    positions = Counter()
    for i in range(30):
        participant = enrol(study, f"p{i}", {}, rng=random.Random(i))
        assignments = list(participant.assignments.select_related("stimulus__system"))
        assert len({a.stimulus_id for a in assignments}) == len(assignments) == 8
        checks = [a for a in assignments if a.is_check]
        assert sorted(a.stimulus.system.role for a in checks) == ["bad", "natural"]
        assert all(a.is_check for a in assignments if a.stimulus.system.role == System.Role.BAD)
        positions.update(a.position for a in checks)
    assert len(positions) >= 6  # checks land all over the sequence, not at fixed places


def test_assignment_balances_loads_and_never_passes_the_target():
    study = make_study(controls=4, clips_per_participant=5, ratings_per_stimulus=3, bad_checks=1, natural_checks=0)
    pool = Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD)
    enrolled = 0
    with pytest.raises(StudyFull):
        for i in range(100):
            enrol(study, f"p{i}", {}, rng=random.Random(i))
            enrolled += 1
            loads = stimulus_loads(study)
            pool_loads = [loads[s.id] for s in pool]
            assert max(pool_loads) - min(pool_loads) <= 1  # least-rated first
            assert max(pool_loads) <= study.ratings_per_stimulus
    assert all(stimulus_loads(study)[s.id] == study.ratings_per_stimulus for s in pool)
    assert Participant.objects.filter(study=study).count() == enrolled  # a full study enrols nobody more


@pytest.mark.parametrize("discard_early", [True, False])
def test_stimulus_loads_count_kept_answers_and_active_reservations_as_a_count_per_assignment_does(discard_early):
    study = make_study(controls=3, clips_per_participant=5, ratings_per_stimulus=9, bad_checks=1, natural_checks=0,
                       reservation_minutes=30, discard_early=discard_early)
    rng = random.Random(0)
    participants = [enrol(study, f"p{i}", {}, rng=random.Random(i)) for i in range(8)]
    long_ago = timezone.now() - timedelta(minutes=31)
    for participant, (idle, finished, excluded) in zip(participants, [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1),
                                                                      (1, 1, 0), (0, 0, 0), (1, 0, 1), (0, 0, 0)]):
        for assignment in participant.assignments.all():
            if rng.random() < 0.5:  # answered, in time or before the clip's end
                Rating.objects.create(assignment=assignment, value=3, answered_before_end=rng.random() < 0.5)
        Participant.objects.filter(pk=participant.pk).update(
            last_seen=long_ago if idle else timezone.now(), finished_at=timezone.now() if finished else None,
            excluded=bool(excluded))
    Stimulus.objects.filter(pk=participants[0].assignments.first().stimulus_id).update(status=Stimulus.Status.RUNNING)
    cutoff = timezone.now() - timedelta(minutes=30)
    expected = Counter()
    for assignment in Assignment.objects.filter(participant__study=study).select_related("participant"):
        participant, rating = assignment.participant, Rating.objects.filter(assignment=assignment).first()
        kept = rating is not None and not (discard_early and rating.answered_before_end)
        held = rating is None and participant.finished_at is None and participant.last_seen >= cutoff
        expected[assignment.stimulus_id] += not participant.excluded and (kept or held)
    loads = stimulus_loads(study, cutoff)
    assert {s: n for s, n in loads.items() if n} == {s: n for s, n in expected.items() if n}
    assert all(loads[s.id] == expected[s.id] for s in Stimulus.objects.filter(study=study))  # 0 where none


def test_an_idle_participant_stops_holding_clips():
    study = make_study(controls=1, clips_per_participant=3, ratings_per_stimulus=1, bad_checks=0, natural_checks=0,
                       reservation_minutes=30)
    first = enrol(study, "idle", {})
    with pytest.raises(StudyFull):
        enrol(study, "second", {})
    Participant.objects.filter(pk=first.pk).update(last_seen=timezone.now() - timedelta(minutes=31))
    assert enrol(study, "second", {}).assignments.count() == 3


def test_nat_attention_checks_never_pass_the_target():
    study = make_study(controls=2, clips_per_participant=4, ratings_per_stimulus=1, bad_checks=1, natural_checks=1)
    for i in range(20):
        try:
            enrol(study, f"p{i}", {}, rng=random.Random(i))
        except StudyFull:
            break
    loads = stimulus_loads(study)
    rated = Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD)
    assert max(loads[s.id] for s in rated) == 1  # NAT included: its ratings are analysed like any system's


def test_an_idle_participant_back_after_their_clips_went_to_others_keeps_only_what_fits():
    study = make_study(controls=1, clips_per_participant=3, ratings_per_stimulus=1, bad_checks=0, natural_checks=0,
                       reservation_minutes=30, training_clips=0)
    idle_client = Client()
    idle = through_practice(idle_client, study, "idle")
    token = on_screen_token(idle_client, study)
    Participant.objects.filter(pk=idle.pk).update(last_seen=timezone.now() - timedelta(minutes=31))
    assert enrol(study, "second", {}).assignments.count() == 3  # the idle one's clips went to the second
    make_shown_long_ago(idle)
    response = post(idle_client, study, "rate", assignment=token, value=3, **WATCHED)
    assert response.status_code == 409 and "given to another participant" in response.content.decode()
    assert Rating.objects.count() == 0
    page = idle_client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert "C0MPL3TE" in page  # nothing left to rate: the completion page
    assert max(stimulus_loads(study).values()) == 1


def test_closing_a_study_lets_participants_under_way_finish():
    study = make_study(clips_per_participant=3)
    client = Client()
    participant = through_practice(client, study)
    rate_current(client, study, participant, 3)
    Study.objects.filter(pk=study.pk).update(is_open=False)
    for _ in range(2):
        assert rate_current(client, study, participant, 3).status_code == 302
    assert "C0MPL3TE" in client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert enter(Client(), study, "latecomer").status_code == 404  # but nobody new starts


def test_practice_shows_a_bad_example_whatever_the_number_of_systems():
    study = make_study(controls=3, training_clips=2, ratings_per_stimulus=100)
    for i in range(10):
        participant = enrol(study, f"p{i}", {}, rng=random.Random(i))
        roles = set(Stimulus.objects.filter(pk__in=participant.training).values_list("system__role", flat=True))
        assert System.Role.BAD in roles and len(participant.training) == 2


def test_only_mturk_may_frame_the_pages_of_an_mturk_study():
    mturk = make_study(platform=Study.Platform.MTURK)
    response = Client().get(reverse("participant-enter", args=[mturk.key]), {"workerId": "W1", "assignmentId": "A1"},
                            follow=True)
    assert "X-Frame-Options" not in response.headers
    assert response.headers["Content-Security-Policy"] == "frame-ancestors https://*.mturk.com"
    prolific = make_study(owner_name="other", platform=Study.Platform.PROLIFIC)
    response = enter(Client(), prolific)
    assert response.headers["X-Frame-Options"] == "DENY" and "Content-Security-Policy" not in response.headers


@pytest.mark.parametrize(("role", "value", "excluded"), [
    (System.Role.BAD, 4, True), (System.Role.BAD, 3, False), (System.Role.NATURAL, 1, True),
    (System.Role.NATURAL, 2, False),
])
def test_attention_checks_flag_the_participant(role, value, excluded):
    study = make_study()
    client = Client()
    participant = through_practice(client, study)
    while (current := current_clip(participant)) is not None:
        is_target = current.stimulus.system.role == role
        rate_current(client, study, participant, value if is_target else 3)
    participant.refresh_from_db()
    assert participant.excluded is excluded
    assert Rating.objects.filter(assignment__participant=participant).count() == study.clips_per_participant


def test_on_a_ten_point_scale_the_thresholds_are_rescaled():
    study = make_study(scale_min=1, scale_max=10)
    rules = StudyRules.of(study).exclusion  # BAD at 7.75 or above, NAT below 3.25
    assert [bool(rules.rated_attention_high("BAD", value, 1, 10)) for value in (7, 8)] == [False, True]
    assert [bool(rules.rated_natural_low("NAT", value, 1, 10)) for value in (3, 4)] == [True, False]


def test_an_answer_sooner_than_the_clip_lasts_is_refused_and_counted():
    study = make_study()  # require_full_play is on by default
    client = Client()
    participant = through_practice(client, study)
    token = on_screen_token(client, study)  # the server has just sent the page: 4 s have not passed
    response = post(client, study, "rate", assignment=token, value=3, **WATCHED)  # whatever the browser claims
    assert response.status_code == 409
    page = response.content.decode()
    assert "Please watch the clip to its end" in page and "it lasts 4.0 s" in page
    assert f'href="{reverse("participant-page", args=[study.key])}"' in page  # back to the clip
    assert Rating.objects.count() == 0
    assert Participant.objects.get(pk=participant.pk).refused_early == 1
    assert on_screen_token(client, study) == token  # the same clip, still to rate
    rate_current(client, study, participant, 3)
    assert Rating.objects.get().answered_before_end is False


def test_the_rating_buttons_are_locked_until_the_end_only_where_the_study_asks():
    for required in (True, False):
        study = make_study(require_full_play=required, title=f"full play {required}")
        client = Client()
        through_practice(client, study, f"pid-{required}")
        page = client.get(reverse("participant-page", args=[study.key])).content.decode()
        buttons = re.findall(r'<button type="submit" name="value"[^>]*>', page)
        assert len(buttons) == 5 and all(("disabled" in b) == required for b in buttons)
        assert ("unlock when the clip has played to its end" in page) == required


def test_without_the_full_play_rule_an_answer_before_the_clip_ends_is_kept_but_flagged():
    study = make_study(require_full_play=False)
    client = Client()
    participant = through_practice(client, study)
    token = on_screen_token(client, study)  # the server has just sent the page: 4 s have not passed
    post(client, study, "rate", assignment=token, value=3, started_s=0.1, answered_s=1.0, played_until_s=0.9)
    rating = Rating.objects.get(assignment__token=token)
    assert rating.answered_before_end and rating.played_until_s == 0.9
    rate_current(client, study, participant, 3, ended_s="")  # the browser never saw the end
    rate_current(client, study, participant, 3)
    flags = [r.answered_before_end for r in Rating.objects.order_by("answered_at", "pk")]
    assert flags == [True, True, False]
    rows = ratings_rows(study)
    assert [r["discarded_early"] for r in rows] == [True, True, False]


def test_bad_ratings_are_refused_and_store_nothing():
    study = make_study()
    client = Client()
    participant = through_practice(client, study)
    token = on_screen_token(client, study)
    make_shown_long_ago(participant)
    assert post(client, study, "rate", assignment=token, value=6).status_code == 400
    assert post(client, study, "rate", assignment=token, value=0).status_code == 400
    assert post(client, study, "rate", assignment=token, value="three").status_code == 400
    assert post(client, study, "rate", assignment=token, value=3, answered_s="soon").status_code == 400
    stranger = through_practice(Client(), study, "pid-2")
    foreign = stranger.assignments.first().token
    assert post(client, study, "rate", assignment=foreign, value=3).status_code == 403
    later = participant.assignments.order_by("position").last().token
    assert post(client, study, "rate", assignment=later, value=3).status_code == 409  # not the one on screen
    assert Rating.objects.count() == 0
    assert post(client, study, "rate", assignment=token, value=3, **WATCHED).status_code == 302
    assert post(client, study, "rate", assignment=token, value=3, **WATCHED).status_code == 409  # repeated
    assert Rating.objects.count() == 1


def test_no_rating_after_completion_or_before_consent():
    study = make_study(clips_per_participant=3, bad_checks=1, natural_checks=1)
    client = Client()
    participant = through_practice(client, study)
    tokens = list(participant.assignments.order_by("position").values_list("token", flat=True))
    for _ in tokens:
        rate_current(client, study, participant, 3)
    assert post(client, study, "rate", assignment=tokens[0], value=3).status_code == 409
    newcomer = Client()
    enter(newcomer, study, "pid-new")
    first = Participant.objects.get(platform_id="pid-new").assignments.first().token
    assert post(newcomer, study, "rate", assignment=first, value=3).status_code == 409
    assert Rating.objects.count() == 3


def test_every_form_needs_its_csrf_token():
    study = make_study()
    client = Client(enforce_csrf_checks=True)
    enter(client, study)
    assert post(client, study, "consent", agree="yes").status_code == 403
    page = client.get(reverse("participant-page", args=[study.key])).content.decode()
    token = re.search(r'name="csrfmiddlewaretoken" value="([^"]+)"', page).group(1)
    assert post(client, study, "consent", agree="yes", csrfmiddlewaretoken=token).status_code == 302


def test_nothing_on_the_participant_pages_names_a_system():
    study = make_study()
    client = Client()
    pages = [enter(client, study).content.decode()]
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    pages.append(client.get(reverse("participant-page", args=[study.key])).content.decode())  # practice
    participant = Participant.objects.get(study=study)
    for index in range(len(participant.training)):
        post(client, study, "practice", index=index)
    pages.append(client.get(reverse("participant-page", args=[study.key])).content.decode())  # rating
    stimulus = current_clip(participant).stimulus
    assert f"/media/stimuli/{stimulus.token}.mp4" in pages[-1]
    for page in pages:
        for system in System.objects.filter(study=study):
            assert not re.search(rf"\b{re.escape(system.name)}\b", page), system.name
        assert "control-" not in page and stimulus.content_key not in page


def test_links_without_the_platform_id_closed_studies_and_missing_sessions_are_refused():
    study = make_study(platform=Study.Platform.PROLIFIC)
    client = Client()
    assert client.get(reverse("participant-enter", args=[study.key])).status_code == 400
    assert client.get(reverse("participant-page", args=[study.key])).status_code == 403
    assert post(client, study, "rate", assignment="0" * 32, value=3).status_code == 403
    study.is_open = False
    study.save()
    assert client.get(reverse("participant-enter", args=[study.key]), {"PROLIFIC_PID": "x"}).status_code == 404
    assert Participant.objects.count() == 0


def test_an_unready_study_enrols_nobody():
    study = make_study()
    Stimulus.objects.update(status=Stimulus.Status.QUEUED)
    response = Client().get(reverse("participant-enter", args=[study.key]), {"PROLIFIC_PID": "x"})
    assert response.status_code == 503 and Participant.objects.count() == 0


def test_mturk_participants_submit_to_mturk_only():
    study = make_study(platform=Study.Platform.MTURK, clips_per_participant=3)
    preview = Client().get(reverse("participant-enter", args=[study.key]),
                           {"assignmentId": "ASSIGNMENT_ID_NOT_AVAILABLE", "hitId": "h"})
    assert "preview" in preview.content.decode() and Participant.objects.count() == 0
    client = Client()
    link = {"workerId": "W1", "assignmentId": "A1", "hitId": "H1"}
    for submit_to in ("https://evil.example.com", "http://www.mturk.com", None):  # nowhere MTurk could take it
        response = client.get(reverse("participant-enter", args=[study.key]),
                              {**link, **({"turkSubmitTo": submit_to} if submit_to else {})})
        assert response.status_code == 400 and "turkSubmitTo" in response.content.decode()
    assert Participant.objects.count() == 0
    client.get(reverse("participant-enter", args=[study.key]), {**link, "turkSubmitTo": "https://workersandbox.mturk.com"})
    participant = through_practice(client, study, "W1")
    for _ in range(3):
        rate_current(client, study, participant, 3)
    done = client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert 'action="https://workersandbox.mturk.com/mturk/externalSubmit"' in done
    assert 'name="assignmentId" value="A1"' in done and "C0MPL3TE" in done


def test_the_export_has_one_row_per_rating_with_the_flags():
    study = make_study(clips_per_participant=3, bad_checks=1, natural_checks=1)
    client = Client()
    participant = through_practice(client, study)
    while (current := current_clip(participant)) is not None:
        rate_current(client, study, participant, 5 if current.stimulus.system.role == System.Role.BAD else 3)
    rows = ratings_rows(study)
    assert len(rows) == 3
    assert {r["participant"] for r in rows} == {participant.code}
    assert all(r["excluded_participant"] for r in rows)
    assert {r["system"] for r in rows} <= {"MoGlow", "RNN", "NAT", "BAD"}
    assert "BAD" in {r["system"] for r in rows}
    # The browser's timings travel with each rating (rate_current posts WATCHED).
    assert {(r["client_started_s"], r["client_ended_s"], r["client_answered_s"], r["played_until_s"])
            for r in rows} == {(0.1, 4.2, 5.0, 4.0)}


def test_participants_finish_while_the_task_queue_is_down():
    from studyapp.server.celery import app

    study = make_study(clips_per_participant=3, bad_checks=1, natural_checks=1)
    dead_broker = "redis://127.0.0.1:1/0"  # nothing listens on port 1
    original = app.conf.broker_url
    app.conf.broker_url = dead_broker
    try:
        client = Client()
        participant = through_practice(client, study)
        for _ in range(3):
            assert rate_current(client, study, participant, 3).status_code == 302
    finally:
        app.conf.broker_url = original
    participant.refresh_from_db()
    assert participant.finished_at is not None


def test_a_rating_step_costs_a_few_queries(django_assert_max_num_queries):
    study = make_study()
    client = Client()
    participant = through_practice(client, study)
    token = on_screen_token(client, study)
    make_shown_long_ago(participant)
    participant.assignments.exclude(token=token).update(shown_at=None)  # the next clip not yet shown
    # The POST (participant with the study's stamp, the clip on screen and the next, the
    # rating, the next clip's shown_at, with the transaction's two statements) and the next
    # page (participant, every clip for the clip and the progress): one commit, no write on the page.
    with django_assert_max_num_queries(8) as queries:
        response = post(client, study, "rate", assignment=token, value=3, **WATCHED)
        page = client.get(response["Location"])
    assert Rating.objects.filter(assignment__token=token).count() == 1
    statements = [query["sql"].split()[0] for query in queries.captured_queries]
    assert statements.count("INSERT") + statements.count("UPDATE") == 2 and statements[-2:] == ["SELECT", "SELECT"]
    on_screen = current_clip(participant)
    assert on_screen.shown_at is not None and on_screen.token in page.content.decode()


def test_an_edit_of_the_study_reaches_participants_already_on_its_pages():
    study = make_study()
    client = Client()
    through_practice(client, study)
    assert study.question in client.get(reverse("participant-page", args=[study.key])).content.decode()
    study.question = "How smooth is the motion?"
    study.save(update_fields=["question"])
    assert "How smooth is the motion?" in client.get(reverse("participant-page", args=[study.key])).content.decode()


def test_last_seen_is_written_once_a_hundredth_of_the_reservation_and_reservations_make_up_for_it():
    study = make_study(reservation_minutes=100, clips_per_participant=4, bad_checks=0, natural_checks=0)
    client = Client()
    participant = through_practice(client, study)
    recent = timezone.now() - timedelta(seconds=30)  # under a minute, the hundredth of 100 minutes
    Participant.objects.filter(pk=participant.pk).update(last_seen=recent)
    rate_current(client, study, participant, 3)
    assert Participant.objects.get(pk=participant.pk).last_seen == recent  # no write for it
    stale = timezone.now() - timedelta(minutes=2)
    Participant.objects.filter(pk=participant.pk).update(last_seen=stale)
    rate_current(client, study, participant, 3)
    assert Participant.objects.get(pk=participant.pk).last_seen > stale
    # A last_seen up to a hundredth late still holds the clips: 100.5 minutes ago is not idle.
    Participant.objects.filter(pk=participant.pk).update(last_seen=timezone.now() - timedelta(minutes=100.5))
    unrated = participant.assignments.filter(rating__isnull=True).values_list("stimulus_id", flat=True)
    assert all(stimulus_loads(study)[s] == 1 for s in unrated)
    Participant.objects.filter(pk=participant.pk).update(last_seen=timezone.now() - timedelta(minutes=102))
    assert all(stimulus_loads(study)[s] == 0 for s in unrated)


def test_the_participant_cookie_is_signed_and_sent_only_to_its_study():
    study = make_study()
    client = Client()
    enter(client, study, "first")
    cookie = client.cookies[f"participant-{study.key}"]
    assert cookie["path"] == f"/p/{study.key}/" and cookie["httponly"]
    other = Participant.objects.create(study=study, platform_id="other")
    pk = str(Participant.objects.get(platform_id="first").pk)
    client.cookies[f"participant-{study.key}"] = cookie.value.replace(pk, str(other.pk), 1)  # a forged id
    assert client.get(reverse("participant-page", args=[study.key])).status_code == 403
