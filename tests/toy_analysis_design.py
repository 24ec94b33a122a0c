"""A toy rating design's analysis, added the way docs/architecture.md says a design's
analysis is added: this module and one entry in ``analysis.designs.DESIGNS``.

Thumbs: one clip a page, thumbs up (value 1) or down (0) on a 0-1 scale, so the rated
clips' rules of `RatingDesign` hold as they are. Its report: the share of thumbs up per
system with a Wilson interval, one sentence per cell, no figures.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from analysis.reports.design_report import DesignReport, exclusion_sentence, in_cell
from analysis.designs.base import RatingDesign
from analysis.stats.preferences import wilson_interval
from analysis.stats.anova import CELL


class Thumbs(RatingDesign):
    name = "thumbs"
    main_table = "thumbs_up"

    def analyse(self, report: DesignReport, kept: pd.DataFrame) -> None:
        shares = kept.groupby([*CELL, "system"])["value"].agg(n="size", up="sum").reset_index()
        shares["share_up"] = shares["up"] / shares["n"]
        shares["ci_low"], shares["ci_high"] = wilson_interval(shares["up"], shares["n"])
        report.tables["thumbs_up"] = ("Share of thumbs up per system (Wilson 95 % intervals)", shares)

    def exclusion_sentence(self, report: DesignReport, row) -> str:
        return exclusion_sentence(report, row, self.rule_text(report.rules, (0, 1)),
                                  f"{row.ratings_collected} clips were judged", row.discarded_participant,
                                  row.discarded_early, row.ratings_kept)

    def cell_sentence(self, report: DesignReport, task: str, control_class: str) -> str:
        shares = in_cell(report.table("thumbs_up"), task, control_class)
        return f" In {control_class}, thumbs up: " + ", ".join(
            f"{r.system} {r.share_up * 100:.0f} % of {r.n}" for r in shares.itertuples(index=False)) + "."

    def write_figures(self, report: DesignReport, folder: Path) -> list[Path]:
        return []
