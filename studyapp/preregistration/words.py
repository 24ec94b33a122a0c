"""A study's locked plan and its deviations in words: the plan page, the report page and
the report's ``plan.md`` read them from ``lock.preregistration``'s data, so a report
made elsewhere from the same data says the same."""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import datetime

from django.core.exceptions import FieldDoesNotExist

from generation.render.camera import Camera
from studyapp.models import Study

NOT_LOCKED = "This study was never opened: no plan was locked before its data came in."


@dataclass(frozen=True)
class PlanInWords:
    locked: bool
    sha256: str
    locked_at: str  # in words, UTC
    sections: list[tuple[str, list[str]]]  # (title, lines)
    deviations: list[tuple[str, str]]  # (when, what), in time order


def _when(iso: str) -> str:
    return datetime.fromisoformat(iso).strftime("%Y-%m-%d %H:%M:%S UTC")


def _shown(value: object) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, dict | list):
        return json.dumps(value, sort_keys=True, ensure_ascii=False)
    return str(value)


def camera_words(camera: dict) -> str:
    """A study's camera (``generation.render.camera.Camera``'s fields; those it lacks at their
    defaults) in words, as the plan states it."""
    c = {**Camera().to_dict(), **camera}
    distance = (f"{c['distance']:g} cm from what it aims at" if c["distance"] is not None else
                f"far enough that the character spans {c['figure_share'] * 100:g} % of the frame's height")
    aim = (f"aimed {c['target_height']:g} cm above the floor" if c["target_height"] is not None else
           f"aimed at {c['target_share'] * 100:g} % of the character's height")
    follow = (f"following the character, its sway smoothed over {c['follow_smoothing']:g} s" if c["follow"]
              else "fixed on the clip's mean floor position")
    return (f"{c['azimuth']:g}° round the vertical and {c['elevation']:g}° above the horizon, {distance}, {aim}, "
            f"{c['fov']:g}° field of view, {follow}; nothing nearer than {c['near']:g} cm is drawn")


def _setting_shown(name: str, value: object) -> str:
    return camera_words(value) if name == "camera" and isinstance(value, dict) else _shown(value)


def _setting_label(name: str) -> str:
    try:
        label = str(Study._meta.get_field(name).verbose_name)
    except FieldDoesNotExist:  # a setting of a later version of the study, read from an older plan's data
        label = name.replace("_", " ")
    return label[:1].upper() + label[1:]


def _system_line(name: str, system: dict) -> str:
    source = f"checkpoint {system['checkpoint_digest'][:12]} ({system['kind']})" if system["checkpoint_digest"] \
        else system["source"]
    return ", ".join(part for part in (f"{name}: {system['role']}", source, f"temperature {system['temperature']:g}")
                     if part)


def _control_line(name: str, control: dict) -> str:
    clip = f", from {control['source_clip']}" if control["source_clip"] else ""
    return f"{name}: {control['origin']}, {control['seconds']:g} s{clip} (SHA-256 {control['sha256'][:12]})"


def participants_sentence(section: dict) -> str:
    """How many participants the plan counts on, and how it reached the number."""
    if section["planned"] is None:
        return f"No planned number of participants: {section['why']}."
    if section["source"] == "targets":
        return (f"{section['planned']} participants: those the study's targets admit (every page answered its "
                "target number of times, each participant answering all their pages).")
    admit = section["targets_admit"]
    short = (f" The targets admit only {admit}: enrolment stops there unless the ratings per clip are raised."
             if admit is not None and admit < section["planned"] else "")
    return (f"{section['planned']} participants, from the power of the design's test: an expected effect of "
            f"{section['expected_effect']:g} ({section['effect_words']}) needs {section['units']} "
            f"{section['unit']}{' per pair' if section['per_pair'] else ''} at α = {section['alpha']:g} "
            f"split over the pairs of {section['compared_systems']} compared systems, with "
            f"{section['power'] * 100:g} % power; a participant gives at least {section['units_per_participant']:.3g} "
            f"of them.{short}")


def deviation_text(row: dict) -> str:
    """One deviation in words."""
    field, old, new = row["field"], row["old"], row["new"]
    if field == "participants":
        return f"{new} participants finished where the plan counted on {old}"
    kind, _, name = field.partition(".")
    if kind in ("system", "control"):
        if old is None:
            return f"{kind} {name} added ({_shown(new)})"
        if new is None:
            return f"{kind} {name} removed (was {_shown(old)})"
        changed = [f"{key} {_shown(old.get(key))} → {_shown(new.get(key))}"
                   for key in sorted(old.keys() | new.keys()) if old.get(key) != new.get(key)]
        return f"{kind} {name} changed: {', '.join(changed)}"
    what = {"setting": lambda: f"setting “{_setting_label(name).lower()}”", "rule": lambda: f"rule {name}"}.get(
        kind, lambda: field)()
    return f"{what}: {_setting_shown(name, old)} → {_setting_shown(name, new)}"


def in_words(preregistration: dict) -> PlanInWords:
    """``lock.preregistration``'s data as the pages show it."""
    if not preregistration["locked"]:
        return PlanInWords(False, "", "", [], [])
    plan = preregistration["plan"]
    design = plan["design"]
    analysis = plan["analysis"]
    sections = [
        ("Design", [f"The {design['name']} design.",
                    *(f"{_setting_label(name)}: {_setting_shown(name, value)}"
                      for name, value in design["settings"].items())]),
        ("Rules", list(plan["rules"]["in_words"])),
        ("Systems", [_system_line(name, system) for name, system in plan["systems"].items()] or ["none"]),
        ("Controls", [_control_line(name, control) for name, control in plan["controls"].items()] or ["none"]),
        ("Planned analysis", [*analysis["tests"], f"Tests at α = {analysis['alpha']:g}; power planned for "
                                                  f"{analysis['power'] * 100:g} %."]),
        ("Participants", [participants_sentence(plan["participants"])]),
    ]
    deviations = [(_when(row["at"]), deviation_text(row)) for row in preregistration["deviations"]]
    return PlanInWords(True, preregistration["sha256"], _when(preregistration["locked_at"]), sections, deviations)


def plan_markdown(preregistration: dict) -> str:
    """The report's ``plan.md``: the plan's hash and time, the plan and its deviations."""
    words = in_words(preregistration)
    if not words.locked:
        return f"# Plan\n\n{NOT_LOCKED}\n"
    lines = ["# Plan", "", f"Locked when the study opened, {words.locked_at}; SHA-256 of its canonical JSON "
             f"(plan.json's `plan`): `{words.sha256}`.", ""]
    for title, items in words.sections:
        lines += [f"## {title}", "", *(f"- {item}" for item in items), ""]
    lines += ["## Deviations from the plan", ""]
    lines += [f"- {when}: {what}" for when, what in words.deviations] or ["None."]
    return "\n".join(lines) + "\n"
