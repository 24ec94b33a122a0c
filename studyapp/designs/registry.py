"""The rating designs a study can have: a table of their names, labels and classes.

The name is what ``Study.design`` stores and the ratings table's ``design`` column says
(``analysis.designs`` reads the same names). A class is named as "module:Class" and
imported when first asked for, so this table imports nothing of the app: the models read
it for the design field's choices, and each design's module imports the models. Adding a
design is one entry here, its module and its templates (docs/architecture.md).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from studyapp.designs.design import Design
    from studyapp.models import Study


@dataclass(frozen=True)
class DesignEntry:
    label: str  # what the researcher chooses by
    implementation: str  # "module:Class", a subclass of designs.design.Design


DESIGNS: dict[str, DesignEntry] = {
    "single": DesignEntry("single clip per page, rated on the scale", "studyapp.designs.single_pages:SingleClip"),
    "side-by-side": DesignEntry("side by side: every system's clip of one control on a page, each on a slider",
                                "studyapp.designs.side_by_side_pages:SideBySide"),
    "pairwise": DesignEntry("pairwise: two systems' clips of one control, which is better",
                            "studyapp.designs.pairwise_pages:Pairwise"),
    "appropriateness": DesignEntry("appropriateness: a system's clip for the shown control beside its clip for "
                                   "another control, which fits better", "studyapp.designs.appropriateness_pages:Appropriateness"),
}
DEFAULT = "single"


def choices() -> list[tuple[str, str]]:
    """(name, label) of every design, for the study's design field."""
    return [(name, entry.label) for name, entry in DESIGNS.items()]


def design_named(name: str) -> Design:
    """The design called ``name``; KeyError naming the known ones for any other."""
    entry = DESIGNS.get(name)
    if entry is None:
        raise KeyError(f"unknown rating design {name!r}; known: {', '.join(DESIGNS)}")
    return _instance(name, entry.implementation)


@cache
def _instance(name: str, implementation: str) -> Design:
    module, _, cls = implementation.partition(":")
    return getattr(importlib.import_module(module), cls)(name)


def design_of(study: Study) -> Design:
    """The design object of ``study``: what its pages show, how they are planned and answered."""
    return design_named(study.design)


def foreign_settings(name: str) -> dict[str, list[str]]:
    """The study fields that other designs read and design ``name`` does not, each with
    the designs that read it (a study of ``name`` leaves them as they are)."""
    own = set(design_named(name).settings)
    owners: dict[str, list[str]] = {}
    for other in DESIGNS:
        for setting in design_named(other).settings:
            if setting not in own:
                owners.setdefault(setting, []).append(other)
    return owners
