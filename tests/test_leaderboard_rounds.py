"""A leaderboard that spans studies: three pairwise rounds (the second adding two systems)
fitted together, checked against a weighted logistic regression of every round's votes
computed here from the stored rows; a round left out; a round removed only while unrated
(on the board page and in the admin); earlier rounds' ratings untouched;
the new systems' first round planned against the board; the researcher's pages behind login,
owner checks and CSRF; the public page off by default and free of participant data."""

from __future__ import annotations

import io
import random
import re

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from analysis.rankings.leaderboard import ELO_PER_LOG_ODDS
from studyapp.designs.pairwise_pages import board_votes
from studyapp.leaderboards.fit import fit_board
from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.leaderboards.public import PUBLIC_COLUMNS
from studyapp.models import Assignment, Participant, Rating, Stimulus, Study, System
from studyapp.participants.assignment import enrol
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db

OLD = (("MoGlow", System.Role.MODEL), ("RNN", System.Role.MODEL), ("NAT", System.Role.NATURAL))
NEW = (("VAE", System.Role.MODEL), ("ERD", System.Role.MODEL))
STRENGTH = {"NAT": 1.2, "MoGlow": 0.4, "RNN": -0.3, "VAE": 0.1, "ERD": -0.8}
# Round 1: the three old systems; round 2 adds VAE and ERD; round 3 compares all five.
ROUNDS = (OLD, OLD + NEW, OLD + NEW)
PARTICIPANTS, PAGES = 6, 8


def round_study(number: int, systems, **fields):
    return make_study(title=f"Round {number} of locomotion", design="pairwise", controls=4, systems=systems,
                      pages_per_participant=PAGES, preference_strengths=2, bad_checks=0, training_clips=0,
                      ratings_per_stimulus=10, **fields)


def store_round_votes(study, seed: int, participants: int = PARTICIPANTS) -> None:
    """``participants`` finished participants, each answering ``PAGES`` pages of random pairs,
    graded as GENEA's five levels from ``STRENGTH`` (a tie when the draw is close)."""
    rng = random.Random(seed)
    clips = {(s.system.name, s.control.name): s for s in Stimulus.objects.filter(study=study).select_related(
        "system", "control")}
    systems = sorted({name for name, _ in clips})
    controls = sorted({control for _, control in clips})
    for n in range(participants):
        person = Participant.objects.create(study=study, platform_id=f"secret-pid-{seed}-{n}",
                                            finished_at=timezone.now())
        for page in range(PAGES):
            left, right = rng.sample(systems, 2)
            control = rng.choice(controls)
            edge = STRENGTH[left] - STRENGTH[right] + rng.gauss(0, 1)
            answer, strength = (("none", None) if abs(edge) < 0.3 else
                                ("left" if edge > 0 else "right", 2 if abs(edge) > 1 else 1))
            for slot, system in ((Assignment.LEFT, left), (Assignment.RIGHT, right)):
                assignment = Assignment.objects.create(participant=person, stimulus=clips[system, control],
                                                       position=2 * page + slot - 1, page=page, slot=slot)
                Rating.objects.create(assignment=assignment, answer=answer, strength=strength)


def three_round_board(owner_name: str = "researcher") -> Leaderboard:
    owner, _ = User.objects.get_or_create(username=owner_name)
    board = Leaderboard.objects.create(owner=owner, title="Locomotion leaderboard")
    for number, systems in enumerate(ROUNDS, start=1):
        study = round_study(number, systems, owner_name=owner_name)
        store_round_votes(study, seed=number)
        Round.objects.create(leaderboard=board, study=study)
    return board


def stored_votes(rounds) -> pd.DataFrame:
    """Every answered page of the rounds' studies, read from the rows themselves: one row per page."""
    rows = []
    for round_ in rounds:
        pages: dict = {}
        for rating in Rating.objects.filter(assignment__participant__study=round_.study).select_related(
                "assignment__stimulus__system"):
            page = pages.setdefault((rating.assignment.participant_id, rating.assignment.page),
                                    {"answer": rating.answer, "strength": rating.strength})
            page["left" if rating.assignment.slot == Assignment.LEFT else "right"] = rating.assignment.stimulus.system.name
        rows += pages.values()
    return pd.DataFrame(rows)


def logistic_elo(pages: pd.DataFrame, anchor: str = "NAT") -> pd.Series:
    """Weighted logistic regression: a row per vote, x = +1 for the left system and -1 for the
    right one (the anchor's column dropped), y = the left one won, weight 2 per degree of
    preference; no preference is a row won by each side, weight 1 each; in Elo, anchor at 1000."""
    systems = sorted(set(pages["left"]) | set(pages["right"]))
    rows, outcome, weight = [], [], []
    for page in pages.itertuples(index=False):
        x = np.zeros(len(systems))
        x[systems.index(page.left)], x[systems.index(page.right)] = 1.0, -1.0
        if page.answer == "none":
            rows += [x, x]
            outcome += [1.0, 0.0]
            weight += [1.0, 1.0]
        else:
            rows.append(x)
            outcome.append(float(page.answer == "left"))
            weight.append(2.0 * page.strength)
    a = systems.index(anchor)
    fit = sm.GLM(np.array(outcome), np.delete(np.array(rows), a, axis=1), family=sm.families.Binomial(),
                 freq_weights=np.array(weight)).fit(tol=1e-13)
    return pd.Series(1000 + ELO_PER_LOG_ODDS * np.insert(fit.params, a, 0.0), index=systems)


def assert_fit_is_the_logistic_fit(board: Leaderboard, rounds) -> None:
    fit = fit_board(board, resamples=200)
    ours = fit.systems.set_index("system")["elo"]
    reference = logistic_elo(stored_votes(rounds))
    assert sorted(ours.index) == sorted(reference.index)
    np.testing.assert_allclose(ours[reference.index], reference, atol=1e-4)


def test_three_rounds_are_fitted_together_as_one_weighted_logistic_regression_of_all_their_votes():
    board = three_round_board()
    rounds = list(board.rounds.order_by("added"))
    assert_fit_is_the_logistic_fit(board, rounds)
    fit = fit_board(board, resamples=200)
    assert sorted(fit.votes["round"].unique()) == [1, 2, 3]  # each vote keeps its round
    assert [r.new_systems for r in fit.rounds] == [["MoGlow", "NAT", "RNN"], ["ERD", "VAE"], []]
    since = fit.systems.set_index("system")
    assert since.loc["VAE", "first_round"] == 2 and since.loc["MoGlow", "first_round"] == 1
    assert since.loc["VAE", "first_round_name"] == "Round 2 of locomotion"
    assert since.loc["NAT", "elo"] == 1000.0 and (fit.systems["anchor"] == "NAT").all()
    # Votes each system rests on: the pages that showed it, over every round.
    shown = stored_votes(rounds)
    for system, row in since.iterrows():
        assert row["pages"] == ((shown["left"] == system) | (shown["right"] == system)).sum()
    assert fit.systems["ci_low"].notna().all() and (fit.systems["ci_low"] <= fit.systems["elo"] + 1e-9).all()


def test_a_round_left_out_is_not_fitted_and_the_board_says_so():
    board = three_round_board()
    rounds = list(board.rounds.order_by("added"))
    rounds[2].in_fit, rounds[2].left_out_because = False, "its controls were the wrong length"
    rounds[2].save()
    assert_fit_is_the_logistic_fit(board, rounds[:2])
    fit = fit_board(board, resamples=0)
    assert "Round 3 (Round 3 of locomotion) is left out of the fit: its controls were the wrong length." in fit.notes
    assert set(fit.votes["round"]) == {1, 2}
    client = Client()
    client.force_login(board.owner)
    page = client.get(reverse("leaderboard", args=[board.pk])).content.decode()
    assert "left out: its controls were the wrong length" in page


def test_leaving_a_round_out_needs_a_reason_and_is_refused_without_one():
    board = three_round_board()
    round_ = board.rounds.order_by("added").last()
    client = Client()
    client.force_login(board.owner)
    url = reverse("leaderboard-round-fit", args=[board.pk, round_.pk])
    response = client.post(url, {f"round-{round_.pk}-left_out_because": ""})
    assert response.status_code == 400 and "say why the round is left out" in response.content.decode()
    round_.refresh_from_db()
    assert round_.in_fit


def test_a_round_nobody_has_rated_can_be_removed_and_its_study_added_to_another_board():
    board = three_round_board()
    mistake = round_study(4, OLD + NEW, adaptive_pairing=True)
    enrol(mistake, "early", {}, rng=random.Random(0))  # enrolled, nothing rated yet
    Round.objects.create(leaderboard=board, study=mistake)
    other = Leaderboard.objects.create(owner=board.owner, title="Gesture leaderboard")
    client = Client()
    client.force_login(board.owner)
    page = client.get(reverse("leaderboard", args=[board.pk])).content.decode()
    assert "Remove round 4" in page and page.count('class="round-remove"') == 1  # the rated rounds offer none
    response = client.post(reverse("leaderboard-remove-round", args=[board.pk, mistake.board_round.pk]))
    assert response.status_code == 302
    page = client.get(response["Location"]).content.decode()
    assert "Took Round 4 of locomotion off the board" in page and board.rounds.count() == 3
    assert Assignment.objects.filter(participant__study=mistake).exists()  # the study itself untouched
    response = client.post(reverse("leaderboard-add-round", args=[other.pk]), {"study": mistake.pk})
    assert response.status_code == 302 and Round.objects.get(study=mistake).leaderboard == other
    assert board_votes(Study.objects.get(pk=mistake.pk)).empty  # its pairing plans against the new board, voteless


def test_a_rated_round_stays_on_its_board_on_the_page_and_in_the_admin():
    from django.contrib import admin
    from django.test import RequestFactory

    from studyapp.leaderboards.admin import RoundInline
    from studyapp.researchers.accounts import grant_researcher_rights

    board = three_round_board()
    first = board.rounds.order_by("added").first()
    round_study(9, OLD, owner_name="stranger")
    stranger = Client()
    stranger.force_login(User.objects.get(username="stranger"))
    url = reverse("leaderboard-remove-round", args=[board.pk, first.pk])
    assert stranger.post(url).status_code == 404
    owner = Client()
    owner.force_login(board.owner)
    response = owner.post(url)
    assert response.status_code == 409
    assert "Round 1 of locomotion has ratings, so it stays on the board" in response.content.decode()
    assert board.rounds.count() == 3
    # The admin holds the rated rounds to the same rule: neither deleted nor given another study.
    grant_researcher_rights(board.owner)
    request = RequestFactory().post("/admin/")
    request.user = board.owner
    formset_class = RoundInline(Leaderboard, admin.site).get_formset(request, board)
    rounds = list(board.rounds.order_by("added", "pk"))
    spare = round_study(5, OLD)

    def posted(changes: dict) -> dict:
        data = {"rounds-TOTAL_FORMS": str(len(rounds)), "rounds-INITIAL_FORMS": str(len(rounds))}
        for n, round_ in enumerate(rounds):
            data |= {f"rounds-{n}-id": str(round_.pk), f"rounds-{n}-leaderboard": str(board.pk),
                     f"rounds-{n}-study": str(round_.study_id), f"rounds-{n}-in_fit": "on"}
        return data | changes

    deleted = formset_class(posted({"rounds-0-DELETE": "on"}), instance=board, prefix="rounds")
    assert not deleted.is_valid() and "has ratings, so it stays on the board" in str(deleted.non_form_errors())
    swapped = formset_class(posted({"rounds-0-study": str(spare.pk)}), instance=board, prefix="rounds")
    assert not swapped.is_valid()
    assert swapped.errors[0]["study"] == ["this round's study has ratings, so it stays the round's study"]
    assert formset_class(posted({}), instance=board, prefix="rounds").is_valid()
    assert board.rounds.count() == 3


def test_fitting_and_showing_the_board_never_changes_a_rounds_ratings():
    board = three_round_board()
    before = list(Rating.objects.order_by("pk").values_list("pk", "answer", "strength", "answered_at",
                                                            "assignment__stimulus_id"))
    client = Client()
    client.force_login(board.owner)
    round_ = board.rounds.order_by("added").first()
    client.post(reverse("leaderboard-round-fit", args=[board.pk, round_.pk]),
                {f"round-{round_.pk}-left_out_because": "a pilot"})
    client.post(reverse("leaderboard-settings", args=[board.pk]), {"title": "Board", "anchor": "NAT", "public": "on"})
    assert client.get(reverse("leaderboard", args=[board.pk])).status_code == 200
    assert Client().get(reverse("leaderboard-public", args=[Leaderboard.objects.get().public_key])).status_code == 200
    after = list(Rating.objects.order_by("pk").values_list("pk", "answer", "strength", "answered_at",
                                                           "assignment__stimulus_id"))
    assert after == before


def test_a_new_systems_first_round_is_planned_against_the_boards_votes():
    owner, _ = User.objects.get_or_create(username="researcher")
    board = Leaderboard.objects.create(owner=owner, title="Board")
    first = round_study(1, OLD)
    store_round_votes(first, seed=1, participants=20)
    Round.objects.create(leaderboard=board, study=first)
    second = round_study(2, OLD + NEW, adaptive_pairing=True)
    alone = round_study(3, OLD + NEW, adaptive_pairing=True)  # the same study, no board
    Round.objects.create(leaderboard=board, study=second)
    prior = board_votes(second)
    assert len(prior) == 20 * PAGES and set(prior["system_left"]) | set(prior["system_right"]) == {"MoGlow", "NAT", "RNN"}
    assert board_votes(alone).empty

    def old_only_pages(study) -> int:
        for n in range(5):
            enrol(study, f"new-{n}", {}, rng=random.Random(n))
        pages: dict = {}
        for a in Assignment.objects.filter(participant__study=study).select_related("stimulus__system"):
            pages.setdefault((a.participant_id, a.page), set()).add(a.stimulus.system.name)
        assert len(pages) == 5 * PAGES
        return sum(systems <= {"MoGlow", "NAT", "RNN"} for systems in pages.values())

    # Without the board the first pages are planned evenly (3 of the 10 pairs are old systems' pairs);
    # against the board, whose votes settle the old systems, nearly every page shows a new one.
    assert old_only_pages(alone) >= 6
    assert old_only_pages(second) <= 4


def test_a_round_left_out_of_the_fit_is_no_prior_of_the_pairing():
    board = three_round_board()
    first, second, _ = board.rounds.order_by("added")
    assert len(board_votes(second.study)) == 2 * PARTICIPANTS * PAGES
    first.in_fit = False
    first.save()
    assert len(board_votes(second.study)) == PARTICIPANTS * PAGES


def test_the_researchers_board_pages_are_behind_login_and_owner_checks():
    board = three_round_board()
    stranger_study = round_study(9, OLD, owner_name="stranger")
    round_ = board.rounds.first()
    gets = [reverse("leaderboard", args=[board.pk]), reverse("leaderboard-csv", args=[board.pk])]
    posts = [(reverse("leaderboard-settings", args=[board.pk]), {"title": "Mine now", "anchor": "NAT"}),
             (reverse("leaderboard-add-round", args=[board.pk]), {"study": stranger_study.pk}),
             (reverse("leaderboard-round-fit", args=[board.pk, round_.pk]),
              {f"round-{round_.pk}-left_out_because": "x"})]
    anonymous = Client()
    for url in gets + [reverse("leaderboard-list")]:
        response = anonymous.get(url)
        assert response.status_code == 302 and response["Location"].startswith("/login/"), url
    stranger = Client()
    stranger.force_login(User.objects.get(username="stranger"))
    for url in gets:
        assert stranger.get(url).status_code == 404, url
    for url, data in posts:
        assert stranger.post(url, data).status_code == 404, url
    assert board.owner.username == "researcher" and Leaderboard.objects.get().title == "Locomotion leaderboard"
    assert Round.objects.get(pk=round_.pk).in_fit
    # The owner cannot add another researcher's study, nor a study that is a round already.
    owner = Client()
    owner.force_login(board.owner)
    for study in (stranger_study, round_.study):
        response = owner.post(reverse("leaderboard-add-round", args=[board.pk]), {"study": study.pk})
        assert response.status_code == 400 and "Select a valid choice" in response.content.decode()
    assert board.rounds.count() == 3


def test_the_board_forms_refuse_a_post_without_its_csrf_token():
    board = three_round_board()
    client = Client(enforce_csrf_checks=True)
    client.force_login(board.owner)
    page = client.get(reverse("leaderboard", args=[board.pk])).content.decode()
    assert page.count('name="csrfmiddlewaretoken"') >= 5  # three rounds, a new round, the settings (and log out)
    response = client.post(reverse("leaderboard-settings", args=[board.pk]), {"title": "x", "anchor": "NAT"})
    assert response.status_code == 403
    assert Leaderboard.objects.get().title == "Locomotion leaderboard"


def test_a_new_board_belongs_to_its_creator_and_its_public_page_is_off_by_default():
    User.objects.create(username="researcher")
    client = Client()
    client.force_login(User.objects.get(username="researcher"))
    response = client.post(reverse("leaderboard-list"), {"title": "My board", "anchor": "NAT"})
    board = Leaderboard.objects.get()
    assert response.status_code == 302 and board.owner.username == "researcher" and not board.public
    assert len(board.public_key) >= 24
    assert Client().get(reverse("leaderboard-public", args=[board.public_key])).status_code == 404
    assert Client().get(reverse("leaderboard-public-csv", args=[board.public_key])).status_code == 404
    assert "The public page is <strong>off</strong>" in client.get(reverse("leaderboard", args=[board.pk])).content.decode()


def _section(html: str) -> str:
    return re.search(r'<section class="public-board".*?</section>', html, re.S).group(0)


def test_the_public_page_shows_the_board_and_no_participant_data_and_the_researcher_sees_the_same():
    board = three_round_board()
    Participant.objects.filter(study__board_round__leaderboard=board).update(exclusion_reason="my cat typed this")
    board.public = True
    board.save()
    public = Client().get(reverse("leaderboard-public", args=[board.public_key]))
    table = Client().get(reverse("leaderboard-public-csv", args=[board.public_key]))
    assert public.status_code == 200 and table.status_code == 200
    html, csv_text = public.content.decode(), table.content.decode()
    rows = pd.read_csv(io.StringIO(csv_text))
    assert list(rows.columns) == list(PUBLIC_COLUMNS) and sorted(rows["system"]) == sorted(STRENGTH)
    assert list(rows["rank"]) == [1, 2, 3, 4, 5] and all(system in html for system in STRENGTH)
    assert "Elo with NAT at 1000; 400 points are odds of 10 to 1" in html  # anchor and origin
    assert 'src="data:image/png;base64,' in html  # the win-rate heat map
    for number in (1, 2, 3):
        assert f"Round {number} of locomotion" in html
    secrets = [*Participant.objects.values_list("platform_id", flat=True), *Participant.objects.values_list("code", flat=True),
               *Stimulus.objects.values_list("token", flat=True), *[s.key for s in [r.study for r in board.rounds.all()]],
               "my cat typed this", "secret-pid"]
    for secret in secrets:
        assert secret not in html and secret not in csv_text, secret
    for researchers_page in ("study-list", "gallery", "analysis", "health", "login"):  # no way in from the public page
        assert f'href="{reverse(researchers_page)}"' not in html, researchers_page
    owner = Client()
    owner.force_login(board.owner)
    researcher_page = owner.get(reverse("leaderboard", args=[board.pk])).content.decode()
    assert _section(researcher_page) == _section(html)  # the preview is the public page's board
    assert board.public_key in researcher_page and "The public page is <strong>on</strong>" in researcher_page


def test_the_public_page_is_fitted_once_a_while_and_again_when_a_round_leaves_the_fit(monkeypatch):
    from studyapp.leaderboards import views

    board = three_round_board()
    board.public = True
    board.save()
    fits = []
    monkeypatch.setattr(views, "fit_board", lambda b: fits.append(b.pk) or fit_board(b, resamples=100))
    url = reverse("leaderboard-public", args=[board.public_key])
    for _ in range(3):
        assert Client().get(url).status_code == 200
    assert Client().get(reverse("leaderboard-public-csv", args=[board.public_key])).status_code == 200
    assert fits == [board.pk]  # visitors do not make the server refit the bootstrap at will
    round_ = board.rounds.last()
    round_.in_fit, round_.left_out_because = False, "a pilot"
    round_.save()
    assert "left out: a pilot" in Client().get(url).content.decode() and fits == [board.pk] * 2


def test_the_admin_shows_a_researcher_their_own_boards_only_and_offers_their_own_pairwise_studies():
    from studyapp.researchers.accounts import grant_researcher_rights

    board = three_round_board()
    stranger_study = round_study(9, OLD, owner_name="stranger")
    stranger = User.objects.get(username="stranger")
    for user in (board.owner, stranger):
        grant_researcher_rights(user)
    client = Client()
    client.force_login(stranger)
    assert "Locomotion leaderboard" not in client.get("/admin/studyapp/leaderboard/").content.decode()
    assert client.get(f"/admin/studyapp/leaderboard/{board.pk}/change/").status_code == 302  # not theirs: away
    client.force_login(board.owner)
    page = client.get(f"/admin/studyapp/leaderboard/{board.pk}/change/").content.decode()
    assert "Round 1 of locomotion" in page and stranger_study.title not in page
