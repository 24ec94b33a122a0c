"""The study app's layering: domain modules know nothing of the task queue."""

from __future__ import annotations

import ast
from pathlib import Path

STUDYAPP = Path(__file__).resolve().parents[1] / "studyapp"
QUEUE_MODULES = ("celery", "kombu", "studyapp.celery", "studyapp.tasks", "studyapp.dispatch", "studyapp.health")


def _imports(module: str) -> set[str]:
    """Every module ``module`` imports, at any level of its code (function bodies included)."""
    tree = ast.parse((STUDYAPP / f"{module.removeprefix('studyapp.').replace('.', '/')}.py").read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def _studyapp_closure(module: str) -> dict[str, set[str]]:
    """``module`` and the studyapp modules it reaches through imports, each with its imports."""
    seen: dict[str, set[str]] = {}
    todo = [module]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen[name] = _imports(name)
        todo += [i for i in seen[name] if i.startswith("studyapp.") and (STUDYAPP / f"{i[9:]}.py").is_file()]
    return seen


def test_stimulus_logic_reaches_no_task_queue_module():
    closure = _studyapp_closure("studyapp.stimuli")
    assert "studyapp.models" in closure  # the walk follows studyapp's own imports
    reached = {name: sorted(i for i in imports if i.split(".")[0] in ("celery", "kombu") or i in QUEUE_MODULES)
               for name, imports in closure.items()}
    assert {name: found for name, found in reached.items() if found} == {}
