"""Rating designs as objects: a new one is a module, its template and one registration,
and no code outside the designs compares a design's name."""

from __future__ import annotations

import re
from datetime import timedelta
from pathlib import Path

import pytest
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from analysis.designs import DESIGNS as ANALYSED_DESIGNS
from studyapp.designs import registry
from studyapp.models import Participant, Rating, Study
from studyapp.researchers.results.export import ratings_rows
from studyapp.researchers.setup.preview import preview_pages
from tests import toy_design
from tests.study_fixtures import make_study
from tests.test_study_participant import enter, post

STUDYAPP = Path(__file__).resolve().parents[1] / "studyapp"
# design ==, design !=, design in, .Design., or == / != a design's constant.
DESIGN_COMPARISON = re.compile(r"design\)? ?(==|!=|not in |in )|\.Design\.|(==|!=) ?(SINGLE|PAIRWISE|SIDE_BY_SIDE|APPROPRIATENESS)\b")


@pytest.fixture
def thumbs(tmp_path, settings, monkeypatch):
    """The toy design registered, its template where Django finds templates."""
    (tmp_path / "studyapp" / "participant").mkdir(parents=True)
    (tmp_path / "studyapp" / "participant" / "thumbs.html").write_text(toy_design.TEMPLATE)
    settings.TEMPLATES = [{**settings.TEMPLATES[0], "DIRS": [tmp_path]}]
    monkeypatch.setitem(registry.DESIGNS, "thumbs", registry.DesignEntry("thumbs up or down", "tests.toy_design:Thumbs"))
    # and its analysis, whose rules and tests the plan locked at opening states (studyapp.preregistration)
    monkeypatch.setitem(ANALYSED_DESIGNS, "thumbs", "tests.toy_analysis_design:Thumbs")


@pytest.mark.django_db
def test_a_new_design_is_one_module_its_template_and_one_registration(thumbs):
    study = make_study(design="thumbs", pages_per_participant=3, training_clips=0)
    study.full_clean()  # a registered design is a valid choice
    assert ("thumbs", "thumbs up or down") in Study._meta.get_field("design").choices
    client = Client()
    enter(client, study)
    post(client, study, "consent", agree="yes")
    post(client, study, "instructions")
    participant = Participant.objects.get(study=study)
    for n in range(1, 4):
        page = client.get(reverse("participant-page", args=[study.key])).content.decode()
        assert f"Clip {n} of 3" in page and "Thumbs up" in page
        token = re.search(r'name="page" value="([0-9a-f]+)"', page).group(1)
        # The rules every design shares hold for this one too: an answer before the clip's end is refused.
        assert post(client, study, "rate", page=token, thumb="up", ended_s=4.1).status_code == 409
        participant.assignments.filter(token=token).update(shown_at=timezone.now() - timedelta(minutes=1))
        assert post(client, study, "rate", page=token, thumb="sideways").status_code == 400
        assert post(client, study, "rate", page=token, thumb="up" if n % 2 else "down", ended_s=4.1).status_code == 302
    assert "C0MPL3TE" in client.get(reverse("participant-page", args=[study.key])).content.decode()
    assert [r.value for r in Rating.objects.order_by("pk")] == [1, 0, 1]
    assert Participant.objects.get(pk=participant.pk).refused_early == 3
    assert [row["value"] for row in ratings_rows(study)] == [1, 0, 1]
    assert [page.template for page in preview_pages(study) if page.name == "a page to rate"] == ["thumbs.html"]


def test_the_built_in_designs_are_the_ones_the_analysis_reads():
    assert set(registry.DESIGNS) == set(ANALYSED_DESIGNS)


def test_no_code_outside_the_designs_compares_a_designs_name():
    found = [f"{path.relative_to(STUDYAPP)}:{number}: {line.strip()}"
             for path in sorted(STUDYAPP.rglob("*.py")) if not path.is_relative_to(STUDYAPP / "designs")
             and "migrations" not in path.parts
             for number, line in enumerate(path.read_text().splitlines(), start=1) if DESIGN_COMPARISON.search(line)]
    assert found == []
