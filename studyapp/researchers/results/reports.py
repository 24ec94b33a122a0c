"""Analysis reports in the study app: a ratings CSV in, the report folder and its tables out.

The app runs exactly the ``analysis`` package's report (the same tables and figures as
``python -m analysis report``), with the exclusion rules it is given (a study's own, for
the study's report), which the folder keeps as rules.json and the page states. A
study's report keeps its locked plan and deviations too (``studyapp.preregistration``): plan.json
as data, plan.md in words, and the page states the plan's hash, time and deviations. The
design of the table says which tables the page shows (``Design.report_tables``). A
report lives in ``MEDIA_ROOT/reports/<digest>/``, named by the SHA-256 of the
researcher, the ratings file and the rules, so the same upload twice is the same report. A report belongs to the researcher who made it (``owner.txt``): only they
see its page and files, since it holds their participants' ratings. The folder is built
under a temporary name and renamed into place, so a failed analysis leaves nothing
behind and a half-written report is never served.

A rerun's report (a study imported with ``import_study --rerun``) also keeps the previous
run's ratings and rules (``previous-ratings.csv``, ``previous-rules.json``) and shows
each run's kept ratings per system side by side (``analysis.ratings.previous_run``), as
``python -m analysis report --previous`` writes them.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from django.conf import settings
from django.utils.html import escape
from django.utils.safestring import SafeString, mark_safe

from analysis.reports.design_report import DesignReport
from analysis.designs import table_design
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import ExclusionRules
from analysis.ratings.previous_run import previous_run_comparison
from analysis.ratings.schema import read_ratings
from analysis.reports.single_report import Report, summary_text, write_report
from analysis.ratings.report import build_report
from analysis.reports.tables import write_table
from generation.files import atomic_folder
from studyapp.researchers.results.table_format import readable_table
from studyapp.designs.registry import design_named
from studyapp.designs.rules import StudyRules
from studyapp.models import Study
from studyapp.preregistration.lock import preregistration
from studyapp.preregistration.words import PlanInWords, in_words, plan_markdown
from studyapp.researchers.results.export import ratings_csv

REPORTS_FOLDER = "reports"
RATINGS_NAME = "ratings.csv"
REFERENCE_NAME = "reference.txt"
RULES_NAME = "rules.json"
OWNER_NAME = "owner.txt"
STUDY_NAME = "study.txt"  # a study's report: the study's id, for the page's link back to it
PLAN_NAME = "plan.json"  # a study's report: its locked plan and deviations (``plan.lock.preregistration``)
PLAN_WORDS_NAME = "plan.md"
PREVIOUS_RATINGS_NAME, PREVIOUS_RULES_NAME = "previous-ratings.csv", "previous-rules.json"
PREVIOUS_TITLE = "This run beside the previous run"


@dataclass(frozen=True)
class ReportPage:
    """What the report page shows."""

    digest: str
    summary: list[SafeString]  # paragraphs
    rules: list[str]  # the exclusion rules applied, in words
    tables: list[tuple[str, SafeString]]  # (title, HTML table)
    figures: list[str]  # paths relative to MEDIA_ROOT
    files: list[str]  # every table file (CSV, Markdown, LaTeX, JSON), relative to MEDIA_ROOT
    notes: list[str]
    plan: PlanInWords | None = None  # a study's report: its plan and deviations (None for an uploaded table)
    study_id: int | None = None  # a study's report: the study it was made from (None for an uploaded table)


def report_folder(media_root: Path, digest: str) -> Path:
    if len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
        raise FileNotFoundError(digest)
    return Path(media_root) / REPORTS_FOLDER / digest


def report_owner(media_root: Path, digest: str) -> int | None:
    """The id of the user a report belongs to; None when there is no such report."""
    try:
        return int((report_folder(media_root, digest) / OWNER_NAME).read_text())
    except (FileNotFoundError, ValueError):
        return None


def create_report(media_root: Path, ratings_csv: bytes, reference: str | None, owner_id: int,
                  rules: ExclusionRules = ExclusionRules(), preregistration: dict | None = None,
                  previous: tuple[str, str] | None = None, study_id: int | None = None) -> str:
    """Analyse a ratings CSV with ``rules`` into its report folder, owned by ``owner_id``; returns the digest.
    A study's ``preregistration`` (its locked plan and deviations) is kept beside it, and its id
    (``study_id``), which the report page links back to.
    ``previous``: a previous run's ratings table and rules, compared with these.

    Raises AnalysisInputError (naming what is wrong) for a table that cannot be analysed.
    """
    plan = json.dumps(preregistration, indent=2, sort_keys=True, ensure_ascii=False) + "\n" if preregistration else ""
    compared = "\0".join(previous).encode() if previous else b""
    digest = hashlib.sha256(f"{owner_id}\0".encode() + ratings_csv + f"\0{reference or ''}\0".encode()
                            + rules.to_json().encode() + (f"\0{plan}".encode() if plan else b"") + compared).hexdigest()
    final = report_folder(media_root, digest)
    if final.is_dir():
        return digest
    with atomic_folder(final) as work:
        if study_id is not None:
            (work / STUDY_NAME).write_text(str(study_id))
        (work / RATINGS_NAME).write_bytes(ratings_csv)
        (work / REFERENCE_NAME).write_text(reference or "")
        (work / RULES_NAME).write_text(rules.to_json())
        (work / OWNER_NAME).write_text(str(owner_id))
        if preregistration:
            (work / PLAN_NAME).write_text(plan, encoding="utf-8")
            (work / PLAN_WORDS_NAME).write_text(plan_markdown(preregistration), encoding="utf-8")
        if previous:
            (work / PREVIOUS_RATINGS_NAME).write_text(previous[0], encoding="utf-8")
            (work / PREVIOUS_RULES_NAME).write_text(previous[1], encoding="utf-8")
        try:
            report = _analyse(work)
            comparison = _previous_run(work, report)
        except AnalysisInputError as error:  # say "the upload", not where the server keeps it
            raise AnalysisInputError(str(error).replace(str(work / RATINGS_NAME), "the uploaded file")) from None
        write_report(report, work)
        if comparison is not None:
            write_table(comparison, work / "tables", "previous_run", caption=PREVIOUS_TITLE)
    return digest


def create_study_report(study: Study, owner_id: int) -> str:
    """The report of a study's ratings so far, as ``python -m analysis report ratings.csv --rules rules.json``
    makes it: the study's rules, and NAT as the reference where it was rated; returns its digest.
    A rerun's report shows its ratings beside the previous run's. Raises AnalysisInputError."""
    previous = study.previous_runs.last()
    return create_report(settings.MEDIA_ROOT, ratings_csv(study), None, owner_id, StudyRules.of(study).exclusion,
                         preregistration(study), (previous.ratings_csv, previous.rules_json) if previous else None,
                         study.pk)


def _rules(folder: Path) -> ExclusionRules:
    """The rules a report was made with (reports made before rules were kept used the defaults)."""
    path = folder / RULES_NAME
    return ExclusionRules.from_json(path.read_text(), RULES_NAME) if path.is_file() else ExclusionRules()


def _analyse(folder: Path) -> Report | DesignReport:
    reference = (folder / REFERENCE_NAME).read_text() or None
    return build_report(read_ratings(folder / RATINGS_NAME), reference=reference, rules=_rules(folder))


def _previous_run(folder: Path, report: Report | DesignReport) -> pd.DataFrame | None:
    """The previous run's kept ratings beside this report's (None for a report without one)."""
    if not (folder / PREVIOUS_RATINGS_NAME).is_file():
        return None
    previous_rules = ExclusionRules.from_json((folder / PREVIOUS_RULES_NAME).read_text(encoding="utf-8"),
                                              PREVIOUS_RULES_NAME)
    previous = read_ratings(folder / PREVIOUS_RATINGS_NAME)
    return previous_run_comparison(read_ratings(folder / RATINGS_NAME), report.rules, previous, previous_rules)


def _paragraphs(markdown: str) -> list[SafeString]:
    """The summary's paragraphs as HTML (it uses only **bold**)."""
    bold = re.compile(r"\*\*(.+?)\*\*")
    return [mark_safe(bold.sub(r"<strong>\1</strong>", str(escape(p.strip())))) for p in markdown.split("\n\n") if p.strip()]


def html_table(table: pd.DataFrame) -> SafeString:
    """A table as escaped HTML for reading (``table_format``), for the report and the monitor."""
    return readable_table(table)


def report_page(media_root: Path, digest: str, owner_id: int) -> ReportPage:
    """The tables and figures of an existing report of ``owner_id`` (re-analysed from its saved ratings).

    Another researcher's report raises FileNotFoundError, as if it did not exist.
    """
    folder = report_folder(media_root, digest)
    if report_owner(media_root, digest) != owner_id or not (folder / RATINGS_NAME).is_file():
        raise FileNotFoundError(digest)
    report = _analyse(folder)
    tables = [(title, html_table(table))
              for title, table in design_named(table_design(report.flagged)).report_tables(report)]
    if (comparison := _previous_run(folder, report)) is not None:
        tables.append((PREVIOUS_TITLE, html_table(comparison)))
    figures = sorted(str(p.relative_to(media_root)) for p in (folder / "figures").glob("*.svg"))
    files = sorted(str(p.relative_to(media_root)) for p in (folder / "tables").iterdir())
    plan_file = folder / PLAN_NAME
    plan = in_words(json.loads(plan_file.read_text(encoding="utf-8"))) if plan_file.is_file() else None
    study_file = folder / STUDY_NAME
    study_id = int(study_file.read_text()) if study_file.is_file() else None
    return ReportPage(digest, _paragraphs(summary_text(report)), report.design.described(report.rules), tables,
                      figures, files, report.notes, plan, study_id)


__all__ = ["AnalysisInputError", "ReportPage", "create_report", "html_table", "report_folder", "report_owner",
           "report_page"]
