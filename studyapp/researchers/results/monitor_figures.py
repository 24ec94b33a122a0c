"""The analysis report's figures of the ratings so far, for the monitor.

The figures are the report's own (``analysis.reports.single_report.report_figures``) of the report the
study's ratings would make now (its ratings table and rules, as ``python -m analysis
report`` reads them), so the monitor shows what the report will. Each is an SVG image
inside the page (a data URI: an image, so nothing in it runs). The analysis runs again
only when the ratings or the rules have changed since the last look: the figures are
kept in Django's cache under the digest of both.
"""

from __future__ import annotations

import base64
import hashlib
import io

import matplotlib.pyplot as plt
from django.core.cache import cache

from analysis.errors import AnalysisInputError
from analysis.ratings.schema import read_ratings
from analysis.reports.single_report import report_figures
from analysis.ratings.report import build_report
from studyapp.designs.rules import StudyRules
from studyapp.models import Study
from studyapp.researchers.results.export import ratings_csv

# What each of the report's figures is called on the monitor.
TITLES = {"means_ci": "Mean rating per system (95 % CI)", "rating_distributions": "Ratings per system",
          "median_mean_ci": "Median and mean rating per system (95 % intervals)",
          "significance_matrix": "Significant differences (Wilcoxon signed-rank, Holm)",
          "preferences": "Preferences per pair", "bradley_terry": "Bradley-Terry strength per system"}
CACHE_SECONDS = 24 * 3600


def _svg_uri(figure) -> str:
    buffer = io.BytesIO()
    with plt.rc_context({"svg.fonttype": "none"}):
        figure.savefig(buffer, format="svg", dpi=110)
    plt.close(figure)
    return "data:image/svg+xml;base64," + base64.b64encode(buffer.getvalue()).decode()


def live_figures(study: Study) -> list[tuple[str, str]]:
    """(title, image URI) of each figure the report of the ratings so far has; empty while
    the ratings are too few for a report."""
    table = ratings_csv(study)
    rules = StudyRules.of(study).exclusion
    key = "monitor-figures:" + hashlib.sha256(table + rules.to_json().encode()).hexdigest()
    figures = cache.get(key)
    if figures is None:
        try:
            report = build_report(read_ratings(io.StringIO(table.decode())), reference=None, rules=rules)
            figures = [(TITLES.get(name, name.replace("_", " ")), _svg_uri(figure))
                       for name, figure in report_figures(report).items()]
        except AnalysisInputError:  # too few ratings yet for the analysis (or none)
            figures = []
        cache.set(key, figures, CACHE_SECONDS)
    return figures


__all__ = ["live_figures"]
