"""The ``import-stylegestures`` command: a checkpoint of the authors' MoGlow code as ours.

The importer (``generation.stylegestures``) imports torch, so it is imported by the
command, and ``--help`` starts quickly.
"""

from __future__ import annotations

import argparse


def import_stylegestures_command(args: argparse.Namespace) -> int:
    from ..stylegestures import import_stylegestures

    out = import_stylegestures(args.checkpoint, args.hparams, args.data, args.out)
    print(f"wrote {out}")
    return 0


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = commands.add_parser("import-stylegestures", help="convert a checkpoint of the authors' MoGlow code",
                            description="Turn a checkpoint saved by the authors' public MoGlow code (StyleGestures, "
                                        "locomotion) into a project checkpoint. It is read as tensors only, never "
                                        "unpickled; the standardisation is refitted from their training data as "
                                        "their code does.")
    p.add_argument("checkpoint", help="their checkpoint (e.g. checkpoints/trained.pkg)")
    p.add_argument("--hparams", required=True, help="the hparams JSON it was trained with")
    p.add_argument("--data", required=True, help="their data folder (all_locomotion_train_<fps>fps.npz)")
    p.add_argument("--out", "-o", required=True, help="the project checkpoint to write (.safetensors)")
    p.set_defaults(run=import_stylegestures_command)
