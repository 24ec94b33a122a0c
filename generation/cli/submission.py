"""``prepare-submission``: a lab's folder of BVH files made into a submission for a
study's exported controls (``generation.submission``)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..files import write_atomic
from ..motion.clip_files import find_bvh_files
from ..motion.root import RootOptions
from ..submission import PATH_TOLERANCE_CM, prepare_submission, read_controls, submission_zip
from .common import add_unit_arguments, up_axis


def prepare(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix.lower() != ".zip":
        raise ValueError(f"{out}: the study's upload takes a .zip; name the output NAME.zip")
    controls = read_controls(args.controls)
    report = prepare_submission(find_bvh_files(args.folder), controls, args.scale, up_axis(args),
                                RootOptions(pairs=args.mirror_pairs), align=not args.keep_root,
                                path_tolerance_cm=args.path_tolerance)
    for line in report.lines():
        print(line)
    if not report.accepted:
        return 2
    write_atomic(out, submission_zip(report))
    print(f"{out}: {len(report.results)} BVH files in centimetres with y up, one per control, for the study's "
          "submitted-motion upload")
    return 0


def _tolerance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"the path tolerance is a positive number of centimetres, got {text!r}")
    return value


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = commands.add_parser(
        "prepare-submission", help="turn a folder of BVH files into a submission for a study's exported controls",
        description="Match the BVH files of FOLDER to the controls a study exported (--controls: the bundle's zip "
                    "or folder), read them in their own unit and up axis, resample each to its control's frame "
                    "rate and length, and move it on the floor so that its root starts where the control starts "
                    "(the origin, facing +z; --keep-root leaves it). A control's file is ID.bvh, or ID_NN.bvh as "
                    "`sample` names clips (the lowest NN). Reports per control what was matched, converted and "
                    "refused; writes the submission only when every control has its clip.")
    p.add_argument("folder", help="folder of .bvh files (or with a data/ subfolder of them)")
    p.add_argument("--controls", required=True, help="the study's exported controls: its zip or folder")
    p.add_argument("--out", "-o", required=True, help="the submission to write (.zip), for the study's systems page")
    p.add_argument("--keep-root", action="store_true",
                   help="leave each clip where it is on the floor instead of moving its start to the control's; "
                        "a root farther off a control's path than the tolerance is refused either way")
    p.add_argument("--path-tolerance", type=_tolerance, default=PATH_TOLERANCE_CM, metavar="CM",
                   help="how far (cm) a clip's root may stray from its control's path before the clip is refused, "
                        "as the study's path tolerance setting (default %(default)g); widen it for motion that "
                        "need not follow the control, such as another lab's natural motion")
    add_unit_arguments(p)
    p.set_defaults(run=prepare)
