"""A rerun's ratings beside its previous run's: per system, what each run kept and what it said.

A study rerun with more systems (the study app's ``import_study --rerun``) is rated
anew by new participants; the previous run's ratings table and rules come with it. Each
run is judged by its own rules (``exclusions``), and its kept ratings that enter the
comparisons (``compared_ratings``) are summarised per system: how many participants and
ratings, and for a design whose clips are rated on a scale the mean and median on that
scale, for one whose pages are answered by a preference the share of its pages a
system's clip was preferred on (pages answered "no preference" counted as not
preferred). The table is long (a row per run and system), runs in the order previous,
this; a system only one run showed has the other's row left out.
"""

from __future__ import annotations

import pandas as pd

from analysis.designs import design_of
from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import ExclusionRules, apply_exclusions, compared_ratings

RUNS = ("previous", "this")


def run_summary(ratings: pd.DataFrame, rules: ExclusionRules) -> pd.DataFrame:
    """Per system: participants and ratings kept, and what the kept ratings say."""
    kept = compared_ratings(apply_exclusions(ratings, rules), rules)
    grouped = kept.groupby("system", sort=True)
    table = pd.DataFrame({"participants": grouped["participant"].nunique(), "ratings": grouped.size()})
    if design_of(ratings).rated:
        table["scale"] = grouped.apply(lambda rows: f"{rows['scale_min'].iloc[0]}-{rows['scale_max'].iloc[0]}",
                                       include_groups=False)
        table["mean"] = grouped["value"].mean()
        table["median"] = grouped["value"].median()
    else:
        table["preferred_share"] = grouped.apply(lambda rows: (rows["answer"] == rows["side"]).mean(),
                                                 include_groups=False)
    return table.reset_index()


def previous_run_comparison(this: pd.DataFrame, this_rules: ExclusionRules, previous: pd.DataFrame,
                            previous_rules: ExclusionRules) -> pd.DataFrame:
    """Both runs' summaries in one tidy table (AnalysisInputError where their designs differ)."""
    designs = design_of(previous).name, design_of(this).name
    if designs[0] != designs[1]:
        raise AnalysisInputError(f"the previous run is a {designs[0]} study and this one a {designs[1]} study: "
                                 "their ratings do not compare")
    runs = [run_summary(previous, previous_rules).assign(run=RUNS[0]),
            run_summary(this, this_rules).assign(run=RUNS[1])]
    table = pd.concat(runs, ignore_index=True)
    table["run"] = pd.Categorical(table["run"], RUNS, ordered=True)
    table = table.sort_values(["system", "run"], kind="stable").reset_index(drop=True)
    table["run"] = table["run"].astype(str)
    return table[["system", "run", *[c for c in table.columns if c not in ("system", "run")]]]


__all__ = ["previous_run_comparison", "run_summary"]
