"""The reference pages are the code's: regenerated, they equal the committed ones; every
environment variable the code reads is declared once in studyapp/server/env.py, every ratings
column a design requires or the study app writes in analysis/ratings/schema.py, and every key of a
study definition file in studyapp/definitions/layout.py."""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

from studyapp.server.env import DECLARED

REPO = Path(__file__).resolve().parents[1]
SPEC = importlib.util.spec_from_file_location("docs_reference", REPO / "scripts" / "docs_reference.py")
docs_reference = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(docs_reference)
READERS = {"env_str", "env_bool", "env_list", "env_float"}
PACKAGES = ("studyapp", "generation", "analysis", "measures")


def environ_reads(tree: ast.AST) -> list[tuple[int, str | None]]:
    """(line, variable name or None) of each os.environ.get / os.environ[...] / os.getenv read."""
    reads = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            target = ast.unparse(node.func)
            if target in ("os.environ.get", "os.getenv"):
                name = node.args[0].value if node.args and isinstance(node.args[0], ast.Constant) else None
                reads.append((node.lineno, name))
        if isinstance(node, ast.Subscript) and ast.unparse(node.value) == "os.environ" and isinstance(node.ctx, ast.Load):
            reads.append((node.lineno, node.slice.value if isinstance(node.slice, ast.Constant) else None))
    return reads


def reader_calls(tree: ast.AST) -> list[tuple[int, str, str, object]]:
    """(line, reader, variable, literal default or None) of each env_* call."""
    calls = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in READERS and node.args:
            default = None
            if len(node.args) > 1:
                try:
                    default = ast.literal_eval(node.args[1])
                except ValueError:  # computed: the declaration says what it is
                    pass
            calls.append((node.lineno, node.func.id, node.args[0].value, default))
    return calls


def sources():
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            yield path, ast.parse(path.read_text(encoding="utf-8"))


def shown(default: object) -> str | None:
    """A literal default as the reference shows it; None for an empty one (the code computes the real one)."""
    if default in ("", [], None):
        return None
    if isinstance(default, bool):
        return "on" if default else "off"
    if isinstance(default, list):
        return ",".join(default)
    if isinstance(default, float | int):
        return f"{default:g}"
    return str(default)


def test_the_study_app_reads_the_environment_only_through_the_declared_readers():
    direct = [f"{path.relative_to(REPO)}:{line}" for path, tree in sources() for line, _ in environ_reads(tree)
              if path.relative_to(REPO).parts[0] == "studyapp" and path.relative_to(REPO) != Path("studyapp/server/env.py")]
    assert direct == [], "read these through studyapp.server.env's readers: " + ", ".join(direct)


def test_every_variable_the_code_reads_is_declared_and_every_declared_one_is_read():
    read = {}
    for path, tree in sources():
        if path.relative_to(REPO) == Path("studyapp/server/env.py"):
            continue
        for line, name in environ_reads(tree):
            read.setdefault(name, f"{path.relative_to(REPO)}:{line}")
        for line, _, name, _ in reader_calls(tree):
            read.setdefault(name, f"{path.relative_to(REPO)}:{line}")
    undeclared = [f"{name} ({where})" for name, where in read.items() if name not in DECLARED]
    assert undeclared == [], ("declare these in studyapp/server/env.py's VARIABLES, then run make docs-reference: "
                              + ", ".join(undeclared))
    assert sorted(DECLARED.keys() - read.keys()) == [], "declared in studyapp/server/env.py but read nowhere"


def test_each_default_written_in_a_readers_call_is_the_declared_one():
    differing = [f"{path.relative_to(REPO)}:{line}: {name} defaults to {shown(default)!r}, declared "
                 f"{DECLARED[name].default!r}"
                 for path, tree in sources() for line, _, name, default in reader_calls(tree)
                 if name in DECLARED and shown(default) is not None and shown(default) != DECLARED[name].default]
    assert differing == []


@pytest.mark.slow
def test_the_committed_reference_pages_are_those_the_code_gives(tmp_path):
    subprocess.run([sys.executable, str(REPO / "scripts" / "docs_reference.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True, cwd=REPO)
    stale = [page.name for page in sorted(tmp_path.glob("*.md"))
             if not (REPO / "docs" / "reference" / page.name).is_file()
             or (REPO / "docs" / "reference" / page.name).read_text(encoding="utf-8") != page.read_text(encoding="utf-8")]
    assert stale == [], f"docs/reference/{', '.join(stale)} differ from the code: run make docs-reference"


def test_generation_help_lists_every_command():
    from generation.cli import parser

    root = parser()
    names = next(action.choices for action in root._actions if hasattr(action, "choices") and action.choices
                 and isinstance(action.choices, dict))
    missing = [name for name in names if name not in root.format_help()]
    assert missing == [], "generation/cli/__init__.py's docstring lists the commands; add " + ", ".join(missing)


def test_every_ratings_column_read_required_or_written_is_declared():
    assert docs_reference.undeclared_columns() == [], "declare these in analysis/ratings/schema.py's COLUMNS"


def test_a_column_the_app_starts_writing_without_a_declaration_is_named(monkeypatch):
    from studyapp.researchers.results import export

    monkeypatch.setattr(export, "EXPORT_COLUMNS", (*export.EXPORT_COLUMNS, "client_volume"))
    assert docs_reference.undeclared_columns() == ["client_volume"]
    with pytest.raises(SystemExit, match="client_volume"):
        docs_reference.ratings_schema_page()


def test_a_column_declared_anew_changes_the_ratings_page(monkeypatch):
    from analysis.ratings import schema as ratings

    before = docs_reference.ratings_schema_page()
    monkeypatch.setattr(ratings, "COLUMNS", (*ratings.COLUMNS, ratings.Column("client_volume", "number", "loudness")))
    assert "| `client_volume` | number |" in docs_reference.ratings_schema_page() != before


def documented_keys(page: str) -> dict[str, set[str]]:
    """Each section of the study file page (## or ###) and the keys its table lists."""
    keys: dict[str, set[str]] = {}
    section = ""
    for line in page.splitlines():
        if line.startswith("#"):
            section = line.lstrip("#").strip()
        elif line.startswith("| `"):
            keys.setdefault(section, set()).add(line.split("`")[1])
    return keys


def definition_keys(definition: dict) -> set[tuple[str, str]]:
    """(the page's section, key) of every key in a definition's values."""
    found = set()
    for top, value in definition.items():
        if isinstance(value, dict):
            for key, item in value.items():
                found.add((top, key))
                if isinstance(item, dict):
                    found |= {(f"{top}.{key}", inner) for inner in item}
        elif isinstance(value, list):
            for entry in value:
                for key, item in entry.items():
                    found.add((top, key))
                    if isinstance(item, dict):
                        found |= {(f"{top}[].{key}", inner) for inner in item}
    return found


def test_every_key_of_the_demos_documented_definition_is_on_the_study_file_page():
    """The definition in docs/running-a-study.md is the demo study's (test_study_definitions holds it to it)."""
    import yaml

    guide = (REPO / "docs" / "running-a-study.md").read_text(encoding="utf-8")
    block = guide.split("# A study definition: python manage.py create_study", 1)[1].split("```", 1)[0].split("\n", 1)[1]
    definition = yaml.safe_load(block)
    keys = documented_keys((REPO / "docs" / "reference" / "study-file.md").read_text(encoding="utf-8"))
    undocumented = sorted(f"{section}: {key}" for section, key in definition_keys(definition)
                          if key not in keys.get(section, set()))
    assert undocumented == [], "declare these in studyapp/definitions/layout.py, then run make docs-reference"
    assert len(definition_keys(definition)) > 50  # the sections, the camera, questions, systems and controls
