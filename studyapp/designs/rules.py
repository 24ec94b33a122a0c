"""A study's rules, built once from its settings and used everywhere they apply.

- Exclusion and discard (``exclusion``, the analysis's ``ExclusionRules``): a participant
  who rates a BAD clip at or above the study's BAD threshold, or a NAT clip below its NAT
  threshold (thresholds on the 1-5 scale, rescaled to the study's), or who prefers BAD on
  a pairwise page, is excluded; a rating given before its clip ended is discarded where
  the study discards early answers. The analysis' object of the study's design states
  them in the words of its report (``described``).
- Refusal: with ``require_full_play``, an answer sent sooner after its page than its
  clips last is refused and never stored (``refuse_before_clip_end``).

The live flags on each answer (``designs.answers``), the monitor, the in-app report and
the ratings export all take them from here; the export writes ``exclusion`` as
rules.json beside ratings.csv, with which ``python -m analysis report --rules`` computes
the in-app report's tables again.
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.designs import design_named as analysed_design
from analysis.ratings.exclusions import ExclusionRules
from studyapp.models import ATTENTION_NAME, NATURAL_NAME, Study


@dataclass(frozen=True)
class StudyRules:
    exclusion: ExclusionRules
    refuse_before_clip_end: bool
    design: str  # the study's design, whose analysis says how the rules read

    @classmethod
    def of(cls, study: Study) -> StudyRules:
        return cls(ExclusionRules(natural_system=NATURAL_NAME, attention_system=ATTENTION_NAME,
                                  bad_at_or_above=study.bad_threshold, natural_below=study.natural_threshold,
                                  discard_early=study.discard_early),
                   refuse_before_clip_end=study.require_full_play, design=study.design)

    def described(self) -> list[str]:
        """The rules in words."""
        return [*analysed_design(self.design).described(self.exclusion),
                "An answer sent sooner after its page than its clips last is refused and never stored."
                if self.refuse_before_clip_end else "Answers are taken however soon they come after their page."]
