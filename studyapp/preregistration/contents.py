"""What a study's plan holds: its design and settings, rules, systems, controls and
planned analysis, as plain JSON data (the number of participants is ``participants.py``'s).

``tracked`` flattens the parts whose change is a deviation into one value per named
part ("setting.ratings_per_stimulus", "rule.bad_at_or_above", "system.MoGlow", ...). The
plan's sentences (the rules and the tests in words) are kept with it for the reader but
not tracked: they follow from the tracked data, and a new wording of the same rule in a
later version of the code is no change to the study.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict

from analysis.levels import ALPHA, POWER
from analysis.designs import design_named as analysed_design
from studyapp.designs.registry import design_of
from studyapp.designs.rules import StudyRules
from studyapp.models import Study

# The settings that shape what participants see and answer, and how many answers are
# sought, besides the design's own (``Design.settings``, its count field); the rules'
# settings (thresholds, early answers, full play) are planned as rules instead.
COMMON_SETTINGS = ("question", "scale_min", "scale_max", "label_min", "label_max", "ratings_per_stimulus",
                   "training_clips", "bad_checks", "instructed_checks", "stop_after_failed_checks", "expected_effect",
                   "device_check", "min_screen_width", "min_screen_height", "video_width", "video_height", "camera")


def canonical_json(data: object) -> str:
    """``data`` as canonical JSON: keys sorted, no spaces, no NaN, non-ASCII kept as UTF-8."""
    return json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def _digest(data: object) -> str:
    return hashlib.sha256(canonical_json(data).encode()).hexdigest()


def planned_settings(study: Study) -> dict:
    design = design_of(study)
    names = sorted({*COMMON_SETTINGS, design.count_field, *design.settings})
    return {name: getattr(study, name) for name in names}


def plan_contents(study: Study) -> dict:
    """The study's plan as it stands now, but for its number of participants."""
    rules = StudyRules.of(study)
    analysed = analysed_design(study.design)
    return {
        "design": {"name": study.design, "settings": planned_settings(study)},
        "rules": {**asdict(rules.exclusion), "refuse_before_clip_end": rules.refuse_before_clip_end,
                  "in_words": rules.described()},
        "systems": {system.name: {"role": system.role, "source": system.source_kind, "kind": system.kind,
                                  "checkpoint_digest": system.checkpoint_digest, "temperature": system.temperature}
                    for system in study.systems.all()},
        "controls": {control.name: {"origin": control.origin, "seconds": control.seconds,
                                    "source_clip": control.source_clip, "sha256": _digest(control.control)}
                     for control in study.controls.all()},
        "analysis": {"design": study.design, "tests": list(analysed.planned_tests), "alpha": ALPHA, "power": POWER},
    }


def tracked(plan: dict) -> dict[str, object]:
    """The parts of ``plan`` whose change is a deviation, one value per part's name."""
    parts: dict[str, object] = {"design": plan["design"]["name"]}
    parts.update((f"setting.{name}", value) for name, value in plan["design"]["settings"].items())
    parts.update((f"rule.{name}", value) for name, value in plan["rules"].items() if name != "in_words")
    parts.update((f"system.{name}", value) for name, value in plan["systems"].items())
    parts.update((f"control.{name}", value) for name, value in plan["controls"].items())
    return parts
