"""The study app's analysis pages: the same report as the analysis command line, behind login."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from django.contrib.auth.models import User

from analysis.ratings.simulate import simulate_pairwise, simulate_ratings, simulate_side_by_side


@pytest.fixture
def media_root(tmp_path: Path, settings) -> Path:
    settings.MEDIA_ROOT = tmp_path
    return tmp_path


@pytest.fixture
def researcher(client):
    user = User.objects.create_user("researcher", password="pw-for-tests")
    client.force_login(user)
    return user


def ratings_csv(**means) -> bytes:
    table = simulate_ratings(means or {"NAT": 4.2, "MoGlow": 3.8, "RNN": 2.9}, 1200, seed=1)
    return table.to_csv(index=False).encode()


def upload(client, data: bytes, reference: str = "NAT"):
    file = io.BytesIO(data)
    file.name = "ratings.csv"
    return client.post("/analysis/", {"ratings": file, "reference": reference})


@pytest.mark.django_db
def test_analysis_pages_require_login(client, media_root):
    response = client.get("/analysis/")
    assert response.status_code == 302 and "/login/" in response["Location"]
    assert client.get("/analysis/" + "0" * 64 + "/").status_code == 302


@pytest.mark.django_db
def test_uploaded_ratings_give_the_report_tables_and_figures(client, media_root, researcher):
    response = upload(client, ratings_csv())
    assert response.status_code == 302
    page = client.get(response["Location"])
    assert page.status_code == 200
    html = page.content.decode()
    assert "Mean ratings ± 95 % CI" in html and "Tukey HSD" in html and "ANOVA" in html
    assert "MoGlow" in html and "<strong>" in html
    folder = next((media_root / "reports").iterdir())
    assert (folder / "figures" / "means_ci.svg").is_file()
    assert f"reports/{folder.name}/figures/means_ci.svg" in html
    assert f"reports/{folder.name}/tables/table2_significance.tex" in html
    # The same upload again is the same report, not a second one.
    assert upload(client, ratings_csv())["Location"] == response["Location"]
    assert len(list((media_root / "reports").iterdir())) == 1


@pytest.mark.django_db
@pytest.mark.parametrize(("table", "expected"), [
    (simulate_side_by_side({"NAT": 75, "A": 60, "B": 50}, 8, seed=1),
     ("Wilcoxon signed-rank tests on per-page differences", "significance_matrix.svg")),
    (simulate_pairwise({"NAT": 1.0, "A": 0.2, "B": 0.0}, 12, seed=1),
     ("Bradley-Terry strengths", "preferences.svg")),
])
def test_side_by_side_and_pairwise_uploads_get_their_own_report(client, media_root, researcher,
                                                                table, expected):
    response = upload(client, table.to_csv(index=False).encode())
    assert response.status_code == 302
    html = client.get(response["Location"]).content.decode()
    assert all(text in html for text in expected)
    assert "Ratings needed for 80 % power per pair" in html and "Tukey HSD" not in html


@pytest.mark.django_db
def test_bad_ratings_are_a_400_naming_the_problem_and_leave_nothing(client, media_root, researcher):
    response = upload(client, b"participant,system,value\np1,NAT,4\n")
    assert response.status_code == 400
    assert "lacks the required column" in response.content.decode()
    response = upload(client, ratings_csv(), reference="GAN")
    assert response.status_code == 400
    assert "reference system &#x27;GAN&#x27; does not exist" in response.content.decode()
    reports = media_root / "reports"
    assert not reports.exists() or list(reports.iterdir()) == []


@pytest.mark.django_db
def test_upload_form_needs_a_csrf_token(media_root, researcher):
    from django.test import Client

    strict = Client(enforce_csrf_checks=True)
    strict.force_login(researcher)
    file = io.BytesIO(ratings_csv())
    file.name = "ratings.csv"
    assert strict.post("/analysis/", {"ratings": file}).status_code == 403
    assert "csrfmiddlewaretoken" in strict.get("/analysis/").content.decode()
