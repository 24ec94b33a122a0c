"""The packages' import structure: each package imports only what docs/architecture.md
allows it, no import cycles, every module importable on its own terms, and the cheap
entry points (the registry, checkpoint headers) free of torch."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

from generation import registry

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("measures", "generation", "analysis", "studyapp", "benchmarks")
# docs/architecture.md's table: the project packages each package may import (besides
# itself), and the outside packages it never imports. Imports go one way, down this list.
MAY_IMPORT = {
    "measures": set(),
    "generation": {"measures"},
    "analysis": {"measures"},
    "studyapp": {"measures", "generation", "analysis"},
    "benchmarks": {"measures", "generation", "analysis", "studyapp"},
}
NEVER_IMPORTS = {
    "measures": {"torch", "django", "celery", "pandas", "scipy", "statsmodels", "matplotlib"},
    "generation": {"django", "celery"},
    "analysis": {"django", "celery", "torch"},
    "studyapp": set(),
    "benchmarks": set(),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    return {module_name(path): path for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py"))}


def import_statements(path: Path) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement of a module: at the top, inside functions and inside
    ``if TYPE_CHECKING:`` blocks alike (an import for type checkers still ties the modules)."""
    return [node for node in ast.walk(ast.parse(path.read_text(), str(path)))
            if isinstance(node, ast.Import | ast.ImportFrom)]


def lazy_imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """The project modules a module imports by name at run time: in a module that calls
    ``import_module``, every string that names a project module, alone or as a registry's
    "module:Class" (``importlib.import_module("analysis.x")``, a table of such names)."""
    tree = ast.parse(path.read_text(), str(path))
    calls = any(isinstance(node, ast.Call) and ast.unparse(node.func).split(".")[-1] == "import_module"
                for node in ast.walk(tree))
    if not calls:
        return set()
    named = {node.value.partition(":")[0] for node in ast.walk(tree)
             if isinstance(node, ast.Constant) and isinstance(node.value, str)}
    return named & set(modules)


def imported_modules(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The project modules that ``name`` imports anywhere in its body, lazily included."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = lazy_imports(path, modules)
    for node in import_statements(path):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
            continue
        base = package
        for _ in range(node.level - 1):
            base = base.rpartition(".")[0]
        source = ".".join(p for p in (base if node.level else "", node.module or "") if p)
        for alias in node.names:
            # "from package import module" imports the module; "from module import name" the module.
            found.add(f"{source}.{alias.name}" if f"{source}.{alias.name}" in modules else source)
    return {m for m in found if m in modules and m != name}


def broken_package_rules(modules: dict[str, Path]) -> list[str]:
    """'module imports name (why not)' for every absolute import that breaks
    ``MAY_IMPORT`` or ``NEVER_IMPORTS``; relative imports stay inside their package."""
    broken = []
    for name, path in sorted(modules.items()):
        package = name.split(".")[0]
        for node in import_statements(path):
            targets = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
                [node.module] if node.level == 0 and node.module else []
            for target in targets:
                top = target.split(".")[0]
                if top in MAY_IMPORT and top != package and top not in MAY_IMPORT[package]:
                    allowed = ", ".join(sorted(MAY_IMPORT[package]))
                    why = f"{package} may import only {allowed}" if allowed else f"{package} imports no other project package"
                    broken.append(f"{name} imports {target} ({why})")
                elif top in NEVER_IMPORTS[package]:
                    broken.append(f"{name} imports {target} ({package} never imports {top})")
    return broken


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` as a list of modules (first repeated last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == 1:
                return path[path.index(target):] + [target]
            if target not in state and (cycle := visit(target)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_the_cycle_finder_sees_a_cycle_through_a_function_level_import(tmp_path):
    modules = {"pkg": tmp_path / "pkg" / "__init__.py", "pkg.a": tmp_path / "pkg" / "a.py", "pkg.b": tmp_path / "pkg" / "b.py"}
    for path in modules.values():
        path.parent.mkdir(exist_ok=True)
    modules["pkg"].write_text("")
    modules["pkg.a"].write_text("from .b import thing\n")
    modules["pkg.b"].write_text("def thing():\n    from . import a\n")
    graph = {name: imported_modules(name, path, modules) for name, path in modules.items()}
    assert find_cycle(graph) == ["pkg.a", "pkg.b", "pkg.a"]
    modules["pkg.b"].write_text("def thing():\n    pass\n")
    graph = {name: imported_modules(name, path, modules) for name, path in modules.items()}
    assert find_cycle(graph) is None


def test_every_package_imports_only_what_its_rules_allow():
    assert broken_package_rules(project_modules()) == []


def test_the_rule_checker_sees_a_forbidden_import_inside_a_function_or_a_type_checking_block(tmp_path):
    modules = {"generation.sliding": tmp_path / "sliding.py", "analysis.units": tmp_path / "units.py",
               "measures.feet": tmp_path / "feet.py"}
    modules["generation.sliding"].write_text(
        "from typing import TYPE_CHECKING\nfrom measures.feet import lower_foot_speed\n"
        "if TYPE_CHECKING:\n    from studyapp.models import Study\n"
        "def ladder():\n    from analysis.smoothness import mean_joint_acceleration\n")
    modules["analysis.units"].write_text("import torch.nn\nfrom . import errors\n")
    modules["measures.feet"].write_text("import numpy as np\nimport pandas as pd\nimport generation\n")
    assert broken_package_rules(modules) == [
        "analysis.units imports torch.nn (analysis never imports torch)",
        "generation.sliding imports studyapp.models (generation may import only measures)",
        "generation.sliding imports analysis.smoothness (generation may import only measures)",
        "measures.feet imports pandas (measures never imports pandas)",
        "measures.feet imports generation (measures imports no other project package)",
    ]


# Circles that counting type-checking and lazy imports found in a package whose rooms are
# split by another change of issue 54; each names its circle.
KNOWN_CIRCLES = {
    "studyapp": "studyapp.models -> studyapp.designs.registry (lazy) -> studyapp.designs.appropriateness -> "
                "studyapp.designs.base -> studyapp.models: broken by the studyapp change",
}


@pytest.mark.parametrize("package", [
    pytest.param(package, marks=pytest.mark.xfail(reason=KNOWN_CIRCLES[package], strict=True))
    if package in KNOWN_CIRCLES else package for package in PACKAGES])
def test_no_module_of_a_package_takes_part_in_an_import_cycle(package):
    """Type-checking and lazy imports (``import_module``, registries' "module:Class")
    count; packages import one way (their rules above), so a circle lies inside one."""
    modules = project_modules()
    graph = {name: imported_modules(name, path, modules) for name, path in modules.items()}
    assert "generation.checkpoint" in graph["generation.train"]  # the parser sees the imports
    inside = {name: {m for m in graph[name] if m.split(".")[0] == package} for name in graph
              if name.split(".")[0] == package}
    cycle = find_cycle(inside)
    assert cycle is None, f"import cycle: {' -> '.join(cycle or [])}"


def test_the_cycle_finder_counts_type_checking_and_lazy_imports(tmp_path):
    modules = {name: tmp_path / f"{name}.py" for name in ("pkg.a", "pkg.b", "pkg.c")}
    modules["pkg.a"].write_text("from pkg.b import thing\n")
    modules["pkg.b"].write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.c import Kind\n")
    modules["pkg.c"].write_text("import importlib\nKINDS = {'a': 'pkg.a:Thing'}\n"
                                "def kind(name):\n    return importlib.import_module(KINDS[name].partition(':')[0])\n")
    graph = {name: imported_modules(name, path, modules) for name, path in modules.items()}
    assert graph == {"pkg.a": {"pkg.b"}, "pkg.b": {"pkg.c"}, "pkg.c": {"pkg.a"}}
    assert find_cycle(graph) == ["pkg.a", "pkg.b", "pkg.c", "pkg.a"]
    modules["pkg.c"].write_text("KINDS = {'a': 'pkg.a:Thing'}\n")  # names only, never imported
    assert imported_modules("pkg.c", modules["pkg.c"], modules) == set()


# docs/architecture.md's picture of analysis/: the rooms each room of analysis/ may import
# (besides itself), bottom to top. "" is the modules directly in analysis/ (errors, levels,
# the page columns, the exclusion rules), below every room; the package's __init__ and
# __main__ are its entry points and may import every room.
ANALYSIS_ROOMS = {
    "": set(),
    "stats": {""},
    "rankings": {"", "stats"},
    "raters": {"", "stats"},
    "motion": {"", "stats"},
    "reports": {"", "stats", "rankings", "raters", "motion"},
    "designs": {"", "stats", "rankings", "raters", "motion", "reports"},
    "ratings": {"", "stats", "rankings", "raters", "motion", "reports", "designs"},
    "cli": {"", "stats", "rankings", "raters", "motion", "reports", "designs", "ratings"},
}
ENTRY = "entry"


def analysis_room(name: str, modules: dict[str, Path]) -> str:
    """The room of an analysis module: its folder below analysis/, "" for a module directly
    in analysis/, ``ENTRY`` for the package itself and ``__main__``."""
    if name in ("analysis", "analysis.__main__"):
        return ENTRY
    folder = name.split(".")[1]
    return folder if f"analysis.{folder}" in modules and modules[f"analysis.{folder}"].name == "__init__.py" else ""


def broken_room_rules(modules: dict[str, Path]) -> list[str]:
    """'module imports module (why not)' for every import between analysis's rooms that
    ``ANALYSIS_ROOMS`` does not allow, type-checking and lazy imports included."""
    broken = []
    for name, path in sorted(modules.items()):
        if name.split(".")[0] != "analysis":
            continue
        room = analysis_room(name, modules)
        for target in sorted(imported_modules(name, path, modules)):
            if target.split(".")[0] != "analysis":
                continue
            other = analysis_room(target, modules)
            if room == ENTRY or other == room or other in ANALYSIS_ROOMS.get(room, set()):
                continue
            why = "nothing imports the entry points" if other == ENTRY else \
                f"analysis/{room or '*.py'} may import only " + ", ".join(
                    f"{r}/" if r else "analysis/*.py" for r in sorted(ANALYSIS_ROOMS.get(room, set()))) \
                if room in ANALYSIS_ROOMS else f"analysis/{room}/ is not a room of docs/architecture.md"
            broken.append(f"{name} imports {target} ({why})")
    return broken


def test_analysis_rooms_import_one_way():
    assert broken_room_rules(project_modules()) == []
    rooms = sorted(ANALYSIS_ROOMS, key=lambda room: len(ANALYSIS_ROOMS[room]))
    for lower, upper in zip(rooms, rooms[1:]):  # one way: no room may import a room that imports it
        assert upper not in ANALYSIS_ROOMS[lower], (lower, upper)


def test_the_room_checker_sees_an_upward_import_in_a_type_checking_block(tmp_path):
    names = ("analysis", "analysis.errors", "analysis.stats", "analysis.stats.anova", "analysis.designs",
             "analysis.designs.base", "analysis.cli", "analysis.cli.main")
    modules = {name: tmp_path / (name.replace(".", "_") + ("/__init__.py" if name.count(".") < 2 and name not in (
        "analysis.errors",) else ".py")) for name in names}
    for path in modules.values():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
    modules["analysis.stats.anova"].write_text(
        "from typing import TYPE_CHECKING\nfrom analysis.errors import AnalysisInputError\n"
        "if TYPE_CHECKING:\n    from analysis.designs.base import RatingDesign\n")
    modules["analysis.designs.base"].write_text("from analysis.stats.anova import CELL\nfrom analysis.cli import main\n")
    modules["analysis.cli.main"].write_text("from analysis.designs.base import RatingDesign\n")
    assert broken_room_rules(modules) == [
        "analysis.designs.base imports analysis.cli.main (analysis/designs may import only analysis/*.py, motion/, "
        "rankings/, raters/, reports/, stats/)",
        "analysis.stats.anova imports analysis.designs.base (analysis/stats may import only analysis/*.py)",
    ]


# At most this many modules (an __init__.py aside) in one folder, so that a newcomer reads
# a folder's names at a glance; Django's numbered migrations and management commands are
# one module per migration or command by Django's rule.
MOST_MODULES = 15
DJANGO_FOLDERS = ("studyapp/migrations", "studyapp/management/commands")
NOT_SPLIT_YET = {  # folders over the limit today, split by their own change (issue 54)
    "generation/motion": "generation/motion/ gained the dataset's four modules; its rooms are still to be drawn",
    "generation/models": "generation/models/ holds one module per model kind; its split is still to be planned",
    "generation": "generation/'s top floor is still to be split into rooms",
}


def module_folders() -> dict[str, int]:
    folders: dict[str, int] = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            folder = path.parent.relative_to(ROOT).as_posix()
            folders[folder] = folders.get(folder, 0) + (path.name != "__init__.py")
    return {folder: count for folder, count in sorted(folders.items()) if folder not in DJANGO_FOLDERS}


@pytest.mark.parametrize("folder", [
    pytest.param(folder, marks=pytest.mark.xfail(reason=NOT_SPLIT_YET[folder], strict=True))
    if folder in NOT_SPLIT_YET else folder for folder in module_folders()])
def test_no_module_folder_holds_more_than_fifteen_modules(folder):
    assert module_folders()[folder] <= MOST_MODULES, f"{folder}/ holds {module_folders()[folder]} modules"


def test_every_generation_module_imports_in_a_fresh_interpreter():
    names = [name for name in project_modules() if name.startswith("generation") and name != "generation.__main__"]
    script = "import importlib\nfor name in %r:\n    importlib.import_module(name)\n" % names
    result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.parametrize("code", [
    "import generation.registry",
    "from generation.checkpoint import read_meta; read_meta('models/moglow-cpu.safetensors')",
])
def test_the_registry_and_checkpoint_headers_load_no_torch(code):
    check = f"{code}\nimport sys\nassert 'torch' not in sys.modules, 'torch was imported'"
    result = subprocess.run([sys.executable, "-c", check], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.parametrize("kind", list(registry.MODELS))
def test_every_registered_kind_names_its_class_and_builds_every_preset_and_ablation(kind):
    cls = registry.model_class(kind)
    assert cls.kind == kind
    entry = registry.MODELS[kind]
    for name in [*entry.presets, *(f"{base}-{ablation}" for base in entry.presets for ablation in entry.ablations)]:
        config = registry.preset(kind, name)
        assert isinstance(config, cls.Config)
        assert set(registry.training_knobs(kind, name)) >= {"learning_rate", "grad_clip", "batch_size"}
    with pytest.raises(KeyError, match="unknown model kind 'gan'"):
        registry.model_class("gan")


# Folders whose files the architecture doc names as a whole: Django's numbered migrations.
NAMED_AS_A_FOLDER = ("studyapp/migrations/",)
PY_PATH = re.compile(r"(?<![\w/.])((?:\w+/)*\w+\.py)\b")
FOLDER_ENTRY = re.compile(r"^(\s*)((?:\w+/)+)(?:\s|$)")


def doc_named_paths(text: str) -> set[str]:
    """The module files and folders (repository paths, folders ending in '/') that an
    architecture doc names: a full path or a dotted module name anywhere; inside a
    package's section (a heading naming ``PACKAGE/``), a path relative to the package, in
    prose or in a tree drawn by indentation, where a file's folder is the entry above it
    with less indentation."""
    named: set[str] = set()
    for path in PY_PATH.findall(text):
        named.add(path)
    for dotted in re.findall(r"\b(?:%s)(?:\.\w+)+" % "|".join(PACKAGES), text):
        parts = dotted.split(".")
        # "generation.store.keep": every prefix may be the module; those that are not never match a file.
        named.update("/".join(parts[:end]) + ".py" for end in range(2, len(parts) + 1))
    package = None
    stack: list[tuple[int, str]] = []
    for line in text.splitlines():
        if heading := re.match(r"^#{1,2} `?(\w+)/`?\s*$", line):
            package, stack = heading.group(1), []
            continue
        if package is None or not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        while stack and stack[-1][0] >= indent:
            stack.pop()
        folder = "".join(name for _, name in stack)
        for path in PY_PATH.findall(line):
            named.add(f"{package}/{folder}{path}")
        if entry := FOLDER_ENTRY.match(line):
            name = "" if entry.group(2) == f"{package}/" and not stack else entry.group(2)
            stack.append((indent, name))
            parts = (folder + name).split("/")[:-1]
            named.update(f"{package}/{'/'.join(parts[:end])}/" for end in range(1, len(parts) + 1))
    # A path through a folder names the folder too ("sqlite_backend/base.py").
    named.update(path[:slash + 1] for path in list(named) for slash in [i for i, c in enumerate(path) if c == "/"])
    return named


def unnamed_modules(text: str) -> list[str]:
    """The project's module files the doc does not name; a package's ``__init__.py`` is
    named by its folder (a tree's entry, or a path through it)."""
    named = doc_named_paths(text)
    missing = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            relative = path.relative_to(ROOT).as_posix()
            if relative.startswith(NAMED_AS_A_FOLDER):
                continue
            if path.name == "__init__.py":
                folder = relative.removesuffix("__init__.py")
                if folder.count("/") == 1 or folder in named:
                    continue
            elif relative in named:
                continue
            missing.append(relative)
    return missing


def test_the_doc_reader_finds_modules_in_trees_prose_and_dotted_names():
    text = ("# Architecture\n\nSee `generation.store.keep`.\n\n## `generation/`\n\n```\ngeneration/\n"
            "  train.py        the loop\n  motion/   arrays\n    bvh.py  types.py   files\n"
            "  cli/\n    data.py  commands\n```\n\nThe unit rule is `motion/units.py`'s.\n\n## `analysis/`\n\n"
            "One module per statistic (`stats.py`).\n")
    named = doc_named_paths(text)
    assert {"generation/store.py", "generation/train.py", "generation/motion/bvh.py", "generation/motion/types.py",
            "generation/cli/data.py", "generation/motion/units.py", "analysis/stats.py",
            "generation/motion/", "generation/cli/"} <= named
    assert "generation/bvh.py" not in named and "analysis/train.py" not in named and "generation/stats.py" not in named


def test_the_architecture_doc_names_every_module():
    assert unnamed_modules((ROOT / "docs" / "architecture.md").read_text()) == []
