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

from analysis.errors import AnalysisInputError
from analysis.design_report import DesignReport
from analysis.exclusions import ExclusionRules, apply_exclusions, exclusion_summary
from analysis.power import more_ratings_for_power
from analysis.ratings import read_ratings, validate_ratings
from analysis.report import Report, build_report, write_report

__all__ = ["AnalysisInputError", "DesignReport", "ExclusionRules", "Report", "apply_exclusions",
           "build_report", "exclusion_summary", "more_ratings_for_power", "read_ratings",
           "validate_ratings", "write_report"]
