"""Analysis of motion rating studies: exclusions, significance tables, objective metrics.

Independent of the models and of the web app: it reads ratings tables (schema in
`analysis.ratings.schema`) and motion as plain arrays (positions (frames, joints, 3) in cm,
y up; fps; joint names and parents), and writes the tables and figures of MoGlow
(Henter et al. 2020) Sec. 5.2-5.3 and HVRNN Sec. 5.2. Entry points:

- `read_ratings`, `build_report`, `write_report`: the whole pipeline (also
  ``python -m analysis report``), in `analysis.ratings`, the entry points a table comes to;
- `analysis.designs`: one object per rating design, which the pipeline asks for all that
  differs between designs (columns, rules, their words, the report's tables and figures);
- `analysis.stats`: ANOVA, Tukey HSD, signed ranks, preferences, multiple comparisons, power;
- `analysis.rankings`: Bradley–Terry, the leaderboard of pairwise votes (Elo with bootstrap
  intervals) and the next pair of an adaptive pairwise study;
- `analysis.raters`: the mixed models (crossed LMM, cumulative link) and rater agreement;
- `analysis.motion`: objective metrics (footsteps, bones, smoothness, Fréchet distance);
- `analysis.reports`: the tables, figures and report folders; `analysis.cli`: the commands.

The rooms import one way (docs/architecture.md): the modules of this folder (errors,
levels, the page columns, the exclusion rules) below all, then stats, then rankings,
raters and motion, then reports, then designs, then ratings, then cli.
"""

from importlib import import_module

# The entry points by the module that defines them, imported when first asked for: the
# web app and the command lines import single modules (analysis.ratings.exclusions, say), and
# importing the package first should not cost them scipy.stats and matplotlib.
_HOME = {"AnalysisInputError": "analysis.errors", "DesignReport": "analysis.reports.design_report",
         "ExclusionRules": "analysis.ratings.exclusions", "apply_exclusions": "analysis.ratings.exclusions",
         "exclusion_summary": "analysis.ratings.exclusions", "more_ratings_for_power": "analysis.ratings.more_ratings",
         "read_ratings": "analysis.ratings.schema", "validate_ratings": "analysis.ratings.schema",
         "Report": "analysis.reports.single_report", "build_report": "analysis.ratings.report",
         "write_report": "analysis.reports.single_report"}

__all__ = sorted(_HOME)


def __getattr__(name: str):
    if name not in _HOME:
        raise AttributeError(f"module 'analysis' has no attribute {name!r}")
    return getattr(import_module(_HOME[name]), name)
