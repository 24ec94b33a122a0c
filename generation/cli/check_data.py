"""``check-data``: which motion folders and takes are expected, what is found, and which committed models apply."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..data_check import MANIFEST, MODELS, check_data, describe, read_manifest


def check(args: argparse.Namespace) -> int:
    folders = args.folder or [os.environ.get("MOTION_DATA") or DEFAULT_DATA]
    folder_checks, model_checks = check_data(folders, Path(args.models), Path(args.manifest))
    for line in describe(folder_checks, model_checks, read_manifest(Path(args.manifest))):
        print(line)
    as_expected = all(check.as_expected for check in folder_checks) and all(m.applies for m in model_checks)
    return 0 if as_expected else 1


# Where the study app looks by default (studyapp/server/settings.py's MOTION_DATA).
DEFAULT_DATA = os.pathsep.join(str(MODELS.parents[1] / "shared" / "data" / name)
                               for name in ("bandai-namco-1", "bandai-namco-2-locomotion"))


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = commands.add_parser(
        "check-data", help="which motion folders and takes are expected, what is found, which models apply",
        description="Compare motion folders with the Bandai-Namco takes the committed models learnt from "
                    "(models/TRAINING-DATA.sha256): takes missing, changed or not expected; then say which "
                    "committed models apply to these folders (their recorded data fingerprint). Exit status 0 "
                    "when everything is as expected, 1 when something differs, 2 when a folder cannot be read.")
    p.add_argument("folder", nargs="*",
                   help="motion folders (or with a data/ subfolder); default $MOTION_DATA, else both folders "
                        "under ../shared/data")
    p.add_argument("--models", default=str(MODELS), help="the folder of committed models (default models/)")
    p.add_argument("--manifest", default=str(MANIFEST),
                   help="the expected takes and their SHA-256 (default models/TRAINING-DATA.sha256)")
    p.set_defaults(run=check)
