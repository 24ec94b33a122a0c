"""The rating designs a study can have: a table of their names, labels and classes.

The name is what ``Study.design`` stores and the ratings table's ``design`` column says
(``analysis.designs`` reads the same names). The table imports nothing of the app: the
models read it for the design field's choices and ask it for a study's design, and each
design's module imports the models, so the designs enter it when the app starts
(``StudyappConfig.ready`` in studyapp/apps.py registers them, in the order the researcher
sees them). Adding a design is its module, its templates and one registration there
(docs/architecture.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any, Protocol


class HasDesign(Protocol):
    design: str  # a registered design's name (a Study)


@dataclass(frozen=True)
class DesignEntry:
    label: str  # what the researcher chooses by
    # A subclass of designs.design.Design, typed loosely here: naming it would import the
    # designs, and through them the models, into the table the models read.
    implementation: type


DESIGNS: dict[str, DesignEntry] = {}
DEFAULT = "single"


def register(name: str, label: str, implementation: type) -> None:
    """Enter design ``name``, chosen by ``label``, made by ``implementation``."""
    DESIGNS[name] = DesignEntry(label, implementation)


def choices() -> list[tuple[str, str]]:
    """(name, label) of every design, for the study's design field."""
    return [(name, entry.label) for name, entry in DESIGNS.items()]


def design_named(name: str) -> Any:
    """The design called ``name`` (a designs.design.Design); KeyError naming the known ones for any other."""
    entry = DESIGNS.get(name)
    if entry is None:
        raise KeyError(f"unknown rating design {name!r}; known: {', '.join(DESIGNS)}")
    return _instance(name, entry.implementation)


@cache
def _instance(name: str, implementation: type) -> Any:
    return implementation(name)


def design_of(study: HasDesign) -> Any:
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
