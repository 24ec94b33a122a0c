"""The appropriateness design in the study app: its mismatched clips, its pages, its answers
and its ratings table as the analysis reads it."""

from __future__ import annotations

import io
import random
import re
from collections import Counter

import pytest
from django.test import Client

from analysis.designs import table_design
from analysis.ratings.exclusions import apply_exclusions
from analysis.ratings.schema import read_ratings
from studyapp.designs.rules import StudyRules
from studyapp.models import Participant, Stimulus, System
from studyapp.participants.assignment import enrol
from studyapp.researchers.results.export import ratings_csv
from studyapp.researchers.setup.readiness import open_warnings
from studyapp.stimuli.clips import plan_stimuli
from studyapp.stimuli.mismatched import study_pairings
from tests.appropriateness_fixtures import MODELS, make_appropriateness_study
from tests.study_fixtures import current_page
from tests.test_study_designs import page_html, page_token, through_practice, watched
from tests.test_study_participant import make_shown_long_ago, post

pytestmark = pytest.mark.django_db

TAKE_PARTNERS = {"left": "right", "right": "left", "straight": "zigzag", "zigzag": "straight", "sharp-left": "left"}
PARTNERS = {**TAKE_PARTNERS, "walk-circle": "sharp-left"}  # a synthetic path may be paired with a take
ATTENTION = {"left": "right", "right": "left", "straight": "sharp-left", "zigzag": "sharp-left", "sharp-left": "right"}


def test_every_control_is_paired_by_the_mismatch_rule_and_nat_gets_attention_partners():
    study = make_appropriateness_study()
    pairings = {p.shown.name: p for p in study_pairings(study)}
    assert {name: p.partner.name for name, p in pairings.items() if p.partner} == PARTNERS
    assert {name: p.attention.name for name, p in pairings.items() if p.attention} == ATTENTION
    still = pairings["stand-still"]
    assert still.partner is None and still.mismatch.reason.startswith("no other control")  # said why
    assert pairings["walk-circle"].attention_check is None  # NAT has no clip of a synthetic path


def test_planning_adds_each_systems_clip_of_the_partner_shown_against_the_control():
    study = make_appropriateness_study()
    mismatched = {(s.system.name, s.control.name, s.shown_control.name)
                  for s in Stimulus.objects.filter(study=study, shown_control__isnull=False)}
    expected = {(system, partner, shown) for system in MODELS for shown, partner in PARTNERS.items()}
    expected |= {("NAT", partner, shown) for shown, partner in TAKE_PARTNERS.items()}
    expected |= {("NAT", partner, shown) for shown, partner in ATTENTION.items()}
    assert mismatched == expected  # none for BAD, whose clips appropriateness pages never show
    own = Stimulus.objects.filter(study=study, shown_control__isnull=True)
    assert own.count() == 3 * 7 + 5  # MoGlow, RNN and Early for every control, NAT for the takes
    assert plan_stimuli(study)[1] == 0  # planning again finds the same rows


def test_a_page_pairs_one_systems_matched_and_mismatched_clips_with_sides_balanced():
    study = make_appropriateness_study(pages_per_participant=8, ratings_per_stimulus=50)
    sides: Counter = Counter()
    for n in range(12):
        participant = enrol(study, f"p{n}", {}, rng=random.Random(n))
        pages: dict[int, list] = {}
        for a in participant.assignments.select_related("stimulus__system", "stimulus__control",
                                                         "stimulus__shown_control").order_by("position"):
            pages.setdefault(a.page, []).append(a)
        assert len(pages) == 8
        checks = [page for page in pages.values() if page[0].is_check]
        assert len(checks) == 1
        for page in pages.values():
            matched = [a for a in page if a.stimulus.shown_control is None]
            mismatched = [a for a in page if a.stimulus.shown_control is not None]
            assert len(matched) == len(mismatched) == 1 and len({a.stimulus.system for a in page}) == 1
            shown = matched[0].stimulus.control.name
            assert mismatched[0].stimulus.shown_control.name == shown
            rule = ATTENTION if page[0].is_check else PARTNERS
            assert mismatched[0].stimulus.control.name == rule[shown]
            if page[0].is_check:
                assert matched[0].stimulus.system.role == System.Role.NATURAL
            sides[matched[0].stimulus_id, mismatched[0].stimulus_id, matched[0].slot] += 1
    shown_pairs = {(matched, mismatched) for matched, mismatched, _ in sides}
    assert len(shown_pairs) > 10
    for matched, mismatched in shown_pairs:  # each pair as often with the matched clip left as right, give or take one
        assert abs(sides[matched, mismatched, 1] - sides[matched, mismatched, 2]) <= 1


def test_an_attention_check_never_repeats_a_rated_page():
    """Left and right are each other's partner and attention partner: NAT's check of either
    would be its rated page again, answered as a check and counted toward that page's
    ratings, so their checks come from the controls with an attention partner of their own."""
    study = make_appropriateness_study(pages_per_participant=8, ratings_per_stimulus=50)
    rated, checks = set(), set()
    for n in range(20):
        participant = enrol(study, f"p{n}", {}, rng=random.Random(n))
        pages: dict[int, list] = {}
        for a in participant.assignments.select_related("stimulus__control", "stimulus__shown_control"):
            pages.setdefault(a.page, []).append(a)
        contents = [frozenset(a.stimulus_id for a in page) for page in pages.values()]
        assert len(set(contents)) == len(contents)  # no page twice for one participant
        for content, page in zip(contents, pages.values()):
            (checks if page[0].is_check else rated).add(content)
            if page[0].is_check:
                shown = next(a.stimulus.control.name for a in page if a.stimulus.shown_control is None)
                assert ATTENTION[shown] != PARTNERS[shown]
    assert checks and not checks & rated


def test_a_study_whose_controls_make_no_attention_check_warns_before_it_opens():
    study = make_appropriateness_study(is_open=False)
    assert open_warnings(study) == []
    study.controls.filter(name__in=["straight", "zigzag", "sharp-left"]).delete()  # left and right are left
    pairings = {p.shown.name: p for p in study_pairings(study)}
    assert pairings["left"].attention == pairings["left"].partner and pairings["left"].checked_with is None
    [warning] = open_warnings(study)
    assert warning.startswith("the settings ask for 1 BAD check(s) per participant, but no finished NAT clip makes one")
    participant = enrol(study, "p0", {}, rng=random.Random(0))
    assert not participant.assignments.filter(is_check=True).exists()  # as warned


def answer_page(client, study, participant, choice_of) -> str:
    """Answer the page on screen with ``choice_of(page)`` -> (answer, strength)."""
    html = page_html(client, study)
    page = current_page(participant)
    make_shown_long_ago(participant)
    answer, strength = choice_of(page)
    data = {"page": page_token(html), "answer": answer, **watched((1, 2)), **({"strength": strength} if strength else {})}
    assert post(client, study, "rate", **data).status_code == 302
    return html


def matched_side(page) -> str:
    return "left" if page[0].stimulus.shown_control_id is None else "right"


def mismatched_side(page) -> str:
    return "right" if matched_side(page) == "left" else "left"


def test_the_page_names_no_system_and_asks_for_five_levels():
    study = make_appropriateness_study()
    client = Client()
    participant = through_practice(client, study)
    html = page_html(client, study)
    assert "orange band on the floor" in html and 'value="1" disabled>slightly<' in html and 'value="2" disabled>clearly<' in html
    # The CSRF token and the study's key are random letters that may spell a name by chance.
    shown = re.sub(r'name="csrfmiddlewaretoken" value="[^"]*"', "", html).replace(study.key, "").replace("natural", "")
    for system in System.objects.filter(study=study):
        assert system.name not in shown
    assert not any(f">{name}<" in html or f" {name} " in html for name in PARTNERS)  # nor the controls
    page = current_page(participant)
    make_shown_long_ago(participant)
    refused = post(client, study, "rate", page=page_token(html), answer="left", strength=3, **watched((1, 2)))
    assert refused.status_code == 400 and b"from 1 to 2" in refused.content
    without = post(client, study, "rate", page=page_token(html), answer="left", **watched((1, 2)))
    assert without.status_code == 400  # a preference needs its strength
    assert current_page(participant) == page


def test_answers_export_as_the_appropriateness_table_and_a_wrong_check_excludes():
    study = make_appropriateness_study()
    careful, careless = Client(), Client()
    for client, pid, on_check in ((careful, "careful", matched_side), (careless, "careless", mismatched_side)):
        participant = through_practice(client, study, pid)
        while page := current_page(participant):
            side = on_check(page) if page[0].is_check else matched_side(page)
            answer_page(client, study, participant, lambda _: (side, 2))
        assert "C0MPL3TE" in page_html(client, study)
    people = {p.platform_id: p for p in Participant.objects.filter(study=study)}
    assert not people["careful"].excluded
    assert people["careless"].excluded and people["careless"].exclusion_reason == \
        "preferred the mismatched clip of a BAD page"

    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    assert table_design(table) == "appropriateness" and len(table) == 2 * 2 * study.pages_per_participant
    pages = table.groupby(["participant", "page"])
    assert (pages["matched"].sum() == 1).all() and (pages["system"].nunique() == 1).all()
    assert (pages["shown_control"].nunique() == 1).all() and (pages["control_class"].nunique() == 1).all()
    assert {"BAD", *MODELS} <= set(table["system"]) <= {"BAD", *MODELS, "NAT"}
    check_rows = table[table["system"] == "BAD"]
    assert len(check_rows) == 4 and set(check_rows["shown_control"]) <= set(ATTENTION)
    flagged = apply_exclusions(table, StudyRules.of(study).exclusion)  # the analysis agrees with the live flag
    assert (flagged["excluded_participant"] == flagged["app_excluded_participant"]).all()
    assert set(flagged.loc[flagged["excluded_participant"], "participant"]) == {people["careless"].code}
    mismatched = table[~table["matched"]]
    rules = [ATTENTION if system == "BAD" else PARTNERS for system in mismatched["system"]]
    assert list(mismatched["made_for"]) == [rule[shown] for rule, shown in zip(rules, mismatched["shown_control"])]


def test_the_stimuli_page_lists_the_pairs_and_the_controls_left_without_a_partner(client):
    study = make_appropriateness_study()
    client.force_login(study.owner)
    html = client.get(f"/studies/{study.pk}/stimuli/").content.decode()
    table = html.split('id="mismatched-pairs"')[1].split("</table>")[0]
    rows = [row for row in table.split("<tr")[2:]]
    assert len(rows) == study.controls.count()
    for shown, partner in PARTNERS.items():
        assert any(f"<td>{shown}</td>" in row and f"<td>{partner}</td>" in row for row in rows), shown
    still = next(row for row in rows if "<td>stand-still</td>" in row)
    assert "<td>none</td>" in still and "no other control" in still
    assert "sharp-left, shown against straight" in html  # NAT's attention clip among the stimuli
    shown_in = {row.split("</td>")[0].rsplit(">", 1)[1]: row for row in rows}  # by the control shown
    for shown in ("left", "right"):  # each the other's partner and attention partner: no check
        assert "is its partner too, so a check would repeat a rated page" in shown_in[shown]
    assert shown_in["straight"].rstrip().endswith(">sharp-left</td></tr>")


def test_the_monitor_and_the_report_show_each_systems_scores(client, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"  # where the report is written
    study = make_appropriateness_study(pages_per_participant=8)
    for n in range(4):
        answerer = Client()
        participant = through_practice(answerer, study, f"p{n}")
        while page := current_page(participant):  # the matched clip clearly better, but RNN's at random
            random_side = random.Random(page[0].pk).choice(("left", "right"))
            side = random_side if page[0].stimulus.system.name == "RNN" else matched_side(page)
            answer_page(answerer, study, participant, lambda _: (side, 2))
    client.force_login(study.owner)
    monitor = client.get(f"/studies/{study.pk}/monitor/").content.decode()
    assert "Share of pages preferring the matched clip" in monitor and "Mean appropriateness score" in monitor
    assert "80 % power" not in monitor
    scores = monitor.split("Mean appropriateness score")[1]
    for system in (*MODELS, "NAT"):
        assert f"<td>{system}</td>" in scores
    report = client.post(f"/studies/{study.pk}/report/", follow=True).content.decode()
    assert "Mean appropriateness score" in report and "share matched" in report
    assert all(f"<td>{system}</td>" in report for system in (*MODELS, "NAT"))


def test_the_demo_reuses_the_motion_another_study_sampled_for_the_same_clips(settings, tmp_path):
    from studyapp.demo import reuse_sampled_motion
    from studyapp.stimuli.sources import sampled_path

    settings.VAR_DIR = tmp_path
    single = make_appropriateness_study("a")
    appropriateness = make_appropriateness_study("b", video_width=320)  # its clips rendered otherwise
    sampled = [s for s in single.stimuli.exclude(system__checkpoint="").filter(shown_control__isnull=True)]
    for stimulus in sampled:
        sampled_path(stimulus).parent.mkdir(parents=True, exist_ok=True)
        sampled_path(stimulus).write_bytes(stimulus.content_key.encode())
    assert reuse_sampled_motion(appropriateness, single) == len(sampled) == 3 * 7
    ours = appropriateness.stimuli.exclude(system__checkpoint="").filter(shown_control__isnull=True)
    theirs = {(s.system.name, s.control.name): sampled_path(s).read_bytes() for s in sampled}
    assert all(sampled_path(s).read_bytes() == theirs[s.system.name, s.control.name] for s in ours)
    assert reuse_sampled_motion(appropriateness, single) == 0  # once


def test_a_label_controlled_page_names_the_shown_controls_action_and_style_in_words():
    from generation.control import AttributeControl
    from studyapp.models import ControlSignal, Study

    study = make_appropriateness_study()
    study.controls.all().delete()
    for action, style in (("walk", "happy"), ("walk", "sad"), ("run", "happy"), ("run", "sad")):
        control = AttributeControl(action, style, 80, 20.0, f"{action}-{style}")
        ControlSignal.objects.create(study=study, name=control.name, origin=ControlSignal.Origin.SYNTHETIC,
                                     control=control.to_dict(), seconds=4.0)
    stimuli, _ = plan_stimuli(study)
    Stimulus.objects.filter(pk__in=[s.pk for s in stimuli]).update(status=Stimulus.Status.DONE, duration_s=4.0)
    client = Client()
    participant = through_practice(client, Study.objects.get(pk=study.pk))
    html = page_html(client, study)
    shown = next(a.stimulus.shown_control or a.stimulus.control for a in current_page(participant))
    action, style = shown.control["action"], shown.control["style"]
    assert f"<strong>{action}</strong>, in a <strong>{style}</strong> style" in html
    assert "orange band" not in html
