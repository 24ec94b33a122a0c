"""Following docs/adding-a-model.md leaves no untracked files in the checkout, and its train
command prepares the data as the demo's MoGlow learnt from it, so its checkpoint joins the
demo's study."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from generation.cli import parser
from generation.cli.common import dataset_units
from generation.cli.models import _contents
from generation.motion.dataset_options import DatasetOptions
from studyapp import demo

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "adding-a-model.md"


def doc_command(program: str) -> list[str]:
    """The doc's command that starts with ``program``, its continued lines joined, as arguments."""
    text = DOC.read_text().replace("\\\n", " ")
    line = next(line for line in text.splitlines() if line.strip().startswith(program))
    return shlex.split(line.strip())


def ignored(path: str) -> bool:
    return subprocess.run(["git", "check-ignore", "-q", path], cwd=REPO).returncode == 0


@pytest.mark.skipif(shutil.which("git") is None or not (REPO / ".git").exists(), reason="not a git checkout")
def test_what_the_plugin_doc_has_you_make_is_ignored_by_git():
    install = doc_command("pip install")
    package = install[-1].removeprefix("./")
    for made in ("build/lib/toy_motion_model/model.py", "toy_motion_model.egg-info/PKG-INFO"):
        assert ignored(f"{package}/{made}"), made  # what pip builds in the package's folder
    train = doc_command("python -m generation train")
    out = Path(train[train.index("--out") + 1])
    for made in (out, out.with_suffix(".best.safetensors"), out.with_suffix(".optim.safetensors")):
        assert ignored(str(made)), made
    assert re.search(rf"add_system STUDY \w+ {re.escape(str(out))}", DOC.read_text())


def test_the_plugin_docs_train_command_prepares_the_data_as_the_demos_moglow_learnt_from_it():
    command = doc_command("python -m generation train")[3:]
    command[command.index("--model") + 1] = "moglow"  # the plugin is not installed here; the data options are the same
    args = parser().parse_args(command)
    options = DatasetOptions(contents=_contents(args), reverse=args.reverse, overlap=args.overlap, **dataset_units(args))
    assert options == DatasetOptions(**demo.DATASET)
