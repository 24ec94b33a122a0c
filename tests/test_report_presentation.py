"""The report page and the monitor as a researcher reads them: figures on the rating scale
(no interval runs past its ends), tables with headers in words and no NaN, the report's
files in one zip with a short list, and the monitor showing the report's own figures of
the ratings so far."""

from __future__ import annotations

import base64
import io
import re
import zipfile

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse

from analysis.reports.design_plots import scale_plot
from analysis.reports.plots import means_plot, rating_scale
from analysis.reports.single_report import report_figures
from analysis import validate_ratings
from analysis.ratings.report import build_report
from analysis.ratings.simulate import simulate_appropriateness, simulate_ratings, simulate_side_by_side
from studyapp.models import Assignment, Participant, Rating
from studyapp.researchers.results.monitor_figures import live_figures
from studyapp.researchers.results.table_format import readable_table
from tests.study_fixtures import make_study


def error_bar_ends(ax) -> np.ndarray:
    """The x of both ends of every error bar drawn on ``ax``."""
    return np.concatenate([segment[:, 0] for collection in ax.collections for segment in collection.get_segments()])


def test_the_mean_ratings_figure_keeps_to_the_scale_however_wide_the_interval():
    # Two ratings of 1 and 5: the 95 % interval runs from -22 to 28 on a 1-5 scale.
    means = pd.DataFrame({"task": "all", "control_class": "held-out", "system": ["NAT", "MoGlow"], "mean": [3.0, 4.0],
                          "ci_low": [-22.4, 3.5], "ci_high": [28.4, 4.5], "ci_half": [25.4, 0.5]})
    figure = means_plot(means, "NAT", (1, 5))
    ax = figure.axes[0]
    low, high = ax.get_xlim()
    assert 0.8 <= low < 1 and 5 < high <= 5.2 and list(ax.get_xticks()) == [1, 2, 3, 4, 5]
    assert sorted(error_bar_ends(ax)) == [1.0, 3.5, 4.5, 5.0]
    plt.close(figure)
    figure = scale_plot(means.assign(median=means["mean"]), [("mean", "mean", "ci_low", "ci_high")], "rating",
                        ["NAT", "MoGlow"], (0, 100))
    assert figure.axes[0].get_xlim() == pytest.approx((-4, 104)) and error_bar_ends(figure.axes[0]).min() == 0
    plt.close(figure)


def test_the_reports_figures_are_drawn_on_the_ratings_scale():
    table = simulate_ratings({"NAT": 4.2, "MoGlow": 3.8, "RNN": 2.9}, 300, seed=1)
    assert rating_scale(table) == (1, 5) and rating_scale(table.drop(columns="scale_max")) is None
    figures = report_figures(build_report(table))
    assert figures["means_ci"].axes[0].get_xlim() == pytest.approx((0.84, 5.16))
    for figure in figures.values():
        plt.close(figure)
    side = simulate_side_by_side({"NAT": 75, "A": 60, "B": 50}, 8, seed=1)
    figures = report_figures(build_report(side))
    assert figures["median_mean_ci"].axes[0].get_xlim() == pytest.approx((-4, 104))
    for figure in figures.values():
        plt.close(figure)


def overlapping_texts(figure) -> list[tuple[str, str]]:
    """The pairs of the figure's axis labels and tick labels whose drawn boxes overlap."""
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    texts = [text for ax in figure.axes for text in (*ax.get_xticklabels(), ax.xaxis.label) if text.get_text()]
    texts += [text for text in figure.texts if text.get_text()]  # the label under the panels
    boxes = [(text.get_text(), text.get_window_extent(renderer)) for text in texts]
    return [(a, b) for i, (a, box) in enumerate(boxes) for b, other in boxes[i + 1:] if box.overlaps(other)]


def test_the_appropriateness_figures_span_the_whole_scales_in_every_panel_with_no_label_overlapping():
    held = simulate_appropriateness({"NAT": 0.92, "MoGlow": 0.78, "RNN": 0.62}, 40, seed=1)
    synthetic = simulate_appropriateness({"MoGlow": 0.7, "RNN": 0.55}, 40, control_class="synthetic", seed=2)
    synthetic["participant"] = "s" + synthetic["participant"]  # NAT has no clip of a synthetic control
    report = build_report(validate_ratings(pd.concat([held, synthetic], ignore_index=True).astype(str)))
    figures = report_figures(report)
    for name, (low, high) in (("appropriateness_scores", (-2, 2)), ("matched_preference", (0, 1))):
        figure = figures[name]
        limits = {ax.get_xlim() for ax in figure.axes}
        assert len(limits) == 1 and min(limits)[0] <= low and min(limits)[1] >= high, (name, limits)  # one range
        assert overlapping_texts(figure) == [], name
        synthetic_panel = next(ax for ax in figure.axes if "synthetic" in ax.get_title())
        rows = dict(zip([t.get_text() for t in figure.axes[0].get_yticklabels()], figure.axes[0].get_yticks()))
        notes = [(text.get_text(), text.get_position()[1]) for text in synthetic_panel.texts]
        assert notes == [("none in this cell", rows["NAT"])], name  # NAT's row says why it is empty
    for figure in figures.values():
        plt.close(figure)


def test_tables_have_headers_in_words_no_nan_and_their_shared_context_said_once():
    power = pd.DataFrame({"task": "all", "control_class": "held-out", "system_a": ["MoGlow", "MoGlow"],
                          "system_b": ["NAT", "RNN"], "effect": [-0.41234, 0.0], "alpha_pair": 0.025,
                          "unit": "ratings per system", "n_now": [12, 12], "power_now": [0.31, np.nan],
                          "n_needed": [57.0, np.nan], "n_more": [45.0, np.nan], "per_participant": [1.5, 1.5],
                          "participants_more": [30.0, np.nan]})
    html = str(readable_table(power))
    assert "n_now" not in html and "NaN" not in html and "nan" not in html
    headers = re.findall(r"<th>(.*?)</th>", html)
    assert headers == ["System A", "System B", "Effect", "So far", "Power so far", "Needed for 80 % power",
                       "More needed", "Per participant", "More participants"]
    assert ("<caption class=\"meta\">Task: all · Control: held-out · Counted in: ratings per system · "
            "α per pair: 0.025</caption>") in html
    assert "<td>-0.4123</td>" in html and "<td>–</td>" in html and "<td>57</td>" in html
    escaped = str(readable_table(pd.DataFrame({"system": ["<b>x</b>"], "n": [3]})))
    assert "&lt;b&gt;x&lt;/b&gt;" in escaped and "<b>" not in escaped


def shown_text(html: str) -> str:
    """A page's text without its markup: a CSRF token or an image's base64 can hold "NaN"
    by chance, a number the page shows cannot."""
    return re.sub(r"<[^>]*>", " ", html)


@pytest.fixture
def researcher(client):
    user = User.objects.create_user("researcher", password="pw-for-tests")
    client.force_login(user)
    return user


@pytest.mark.django_db
def test_the_report_page_folds_its_files_into_one_zip_and_a_short_list(client, researcher, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    file = io.BytesIO(simulate_ratings({"NAT": 4.2, "MoGlow": 3.8, "RNN": 2.9}, 300, seed=1).to_csv(index=False).encode())
    file.name = "ratings.csv"
    page_url = client.post("/analysis/", {"ratings": file, "reference": "NAT"})["Location"]
    page = client.get(page_url)
    html = page.content.decode()
    digest = page_url.strip("/").split("/")[-1]
    zip_url = reverse("analysis-report-zip", args=[digest])
    assert f'href="{zip_url}"' in html and "Download all (zip)" in html
    short = re.search(r'<ul class="files" id="csv-files">(.*?)</ul>', html, re.S).group(1)
    folder = tmp_path / "reports" / digest
    every = sorted(p for p in folder.rglob("*") if p.is_file() and p.name != "owner.txt")
    assert short.count("<li>") == len(list((folder / "tables").glob("*.csv"))) < len(every) / 3
    text = shown_text(html)
    assert "NaN" not in text and "n_now" not in text
    response = client.get(zip_url)
    assert response.status_code == 200 and response["Content-Type"] == "application/zip"
    with zipfile.ZipFile(io.BytesIO(response.content)) as archive:
        names = sorted(archive.namelist())
        assert names == sorted(f"report-{digest[:12]}/{p.relative_to(folder).as_posix()}" for p in every)
        assert archive.read(f"report-{digest[:12]}/ratings.csv") == (folder / "ratings.csv").read_bytes()
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert stranger.get(zip_url).status_code == 404


def rate_everything(study, value_of) -> None:
    """Each clip rated by three participants of its own (one page each), ``value_of(system)``."""
    for i, stimulus in enumerate(study.stimuli.select_related("system")):
        for k in range(3):
            participant = Participant.objects.create(study=study, platform_id=f"p{i}-{k}")
            assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=0)
            Rating.objects.create(assignment=assignment, value=value_of(stimulus.system.name, k),
                                  client_answered_s=5.0, played_until_s=4.0)


@pytest.mark.django_db
def test_the_monitor_shows_the_reports_figures_of_the_ratings_so_far(settings):
    settings.CACHES = {"default": {"BACKEND": "django.core.cache.backends.locmem.LocMemCache"}}
    study = make_study(controls=2, bad_checks=0)
    assert live_figures(study) == []  # no ratings: no report yet
    means = {"MoGlow": 3, "RNN": 2, "NAT": 4, "BAD": 1}
    rate_everything(study, lambda system, k: max(1, min(5, means[system] + k - 1)))
    figures = live_figures(study)
    assert [title for title, _ in figures] == ["Mean rating per system (95 % CI)", "Ratings per system"]
    svg = base64.b64decode(figures[0][1].removeprefix("data:image/svg+xml;base64,")).decode()
    assert svg.lstrip().startswith("<?xml") and "MoGlow" in svg and "mean rating (95 % CI)" in svg
    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    assert page.count('<img src="data:image/svg+xml;base64,') == 2 and "Figures of the ratings so far" in page
    text = shown_text(page)
    assert "n_now" not in text and "NaN" not in text
