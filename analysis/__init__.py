"""Analysis of motion rating studies: exclusions, significance tables, objective metrics.

Independent of the models and of the web app: it reads ratings tables (schema in
`analysis.ratings`) and motion as plain arrays (positions (frames, joints, 3) in cm,
y up; fps; joint names and parents), and writes the tables and figures of MoGlow
(Henter et al. 2020) Sec. 5.2-5.3 and HVRNN Sec. 5.2. Entry points:

- `read_ratings`, `build_report`, `write_report`: the whole pipeline (also
  ``python -m analysis report``);
- `analysis.designs`: one object per rating design, which the pipeline asks for all that
  differs between designs (columns, rules, their words, the report's tables and figures);
- `analysis.stats`, `analysis.mixed`: ANOVA, Tukey HSD, CIs, the mixed model;
- `analysis.side_by_side`, `analysis.pairwise`, `analysis.bradley_terry`: the statistics
  of side-by-side and pairwise designs (`analysis.designs`);
- `more_ratings_for_power` (`analysis.power`): ratings needed for 80 % power per pair;
- `analysis.leaderboard`, `analysis.pairing`: the leaderboard of pairwise votes (Elo with
  bootstrap intervals) and the next pair of an adaptive pairwise study;
- `analysis.crossed_mixed`, `analysis.ordinal_mixed`, `analysis.agreement`: the crossed
  LMM, the cumulative link mixed model and rater agreement;
- `analysis.footsteps`, `analysis.bones`, `analysis.scores`: objective metrics.
"""

from importlib import import_module

# The entry points by the module that defines them, imported when first asked for: the
# web app and the command lines import single modules (analysis.exclusions, say), and
# importing the package first should not cost them scipy.stats and matplotlib.
_HOME = {"AnalysisInputError": "analysis.errors", "DesignReport": "analysis.design_report",
         "ExclusionRules": "analysis.exclusions", "apply_exclusions": "analysis.exclusions",
         "exclusion_summary": "analysis.exclusions", "more_ratings_for_power": "analysis.power",
         "read_ratings": "analysis.ratings", "validate_ratings": "analysis.ratings",
         "Report": "analysis.report", "build_report": "analysis.report", "write_report": "analysis.report"}

__all__ = sorted(_HOME)


def __getattr__(name: str):
    if name not in _HOME:
        raise AttributeError(f"module 'analysis' has no attribute {name!r}")
    return getattr(import_module(_HOME[name]), name)
