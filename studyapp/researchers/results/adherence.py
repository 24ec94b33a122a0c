"""How closely the study's motion follows its controls, and whether that is what the
participants' appropriateness answers say: the analysis package's control-adherence
metrics over the study's own motion export.

The motion is written as ``export_motion`` writes it (``stimuli.motion_export``, with
each path clip's control and root paths) into a temporary folder and read back by
``analysis.motion.motion_io``, so the page gives the tables ``python -m analysis objective
DIR --appropriateness ratings.csv`` gives for the same files: per system the root's
distance from its control's path and its heading error (``analysis.reports.adherence``), and,
in an appropriateness study with kept pages, their correlation across systems with the
mean appropriateness scores. Label-controlled studies have no paths: their adherence is
how often HVRNN's attribute classifiers see the asked labels in the clips, which the
export's label side files let ``python -m generation hvrnn-label`` count outside the app
(LABEL_NOTE); the app keeps no classifiers' file to run them itself.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import pandas as pd

from analysis.reports.adherence import adherence_correlation, path_adherence
from analysis.stats.matching import appropriateness_pages
from analysis.designs import design_of
from analysis.ratings.exclusions import compared_ratings
from analysis.motion.motion_io import load_motion_sets
from studyapp.designs.rules import StudyRules
from studyapp.models import Study
from studyapp.researchers.results.monitor import flagged_ratings
from studyapp.stimuli.motion_export import write_motion


LABEL_NOTE = ("The clips of label controls follow no path: their adherence is how often HVRNN's attribute classifiers "
              "see the labels they were asked for. The motion download has each clip's asked labels beside its BVH "
              "file; python -m generation hvrnn-label FOLDER --classifiers FILE --out labels.csv on a system's "
              "folder says how often the classifiers agree with them.")


def adherence_tables(study: Study) -> tuple[list[tuple[str, pd.DataFrame]], list[str]]:
    """(title, table) of the control adherence and, with appropriateness answers, its
    correlation with the scores; and notes saying what could not be measured."""
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch) / "motion"
        write_motion(study, folder)
        motion = load_motion_sets([folder]) if any(folder.iterdir()) else {}
    adherence, _, notes = path_adherence(motion)
    if study.controls.filter(control__type="attributes").exists():
        notes.append(LABEL_NOTE)
    if adherence.empty:
        return [], [*notes, "No clip of the study follows a path, so there is no path adherence to measure."]
    tables = [("Control adherence: the root's distance from the control's path (cm) and its heading error "
               "(degrees), mean over time and at the end", adherence)]
    scores = _mean_scores(study)
    if scores is None:
        notes.append("The correlation with the appropriateness scores needs an appropriateness study with kept pages.")
    else:
        correlation, correlation_notes = adherence_correlation(scores, adherence)
        tables.append(("Pearson correlation across systems of the mean appropriateness score with each "
                       "adherence metric", correlation))
        notes += correlation_notes
    return tables, notes


def _mean_scores(study: Study) -> pd.Series | None:
    """Each compared system's mean appropriateness score over the kept pages (None: no such pages)."""
    flagged = flagged_ratings(study)
    if flagged.empty or not design_of(flagged).judges_appropriateness:
        return None
    compared = compared_ratings(flagged, StudyRules.of(study).exclusion)
    if compared.empty:
        return None
    return appropriateness_pages(compared).groupby("system")["score"].mean()


__all__ = ["adherence_tables"]
