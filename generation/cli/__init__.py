"""Command line of the generation package: ``python -m generation COMMAND --help``.

  info PATH             describe a BVH file or a dataset (.npz)
  check-data [FOLDER...]
                        which motion folders and takes are expected, what is found, which committed models apply
  build-dataset FOLDER  encode a folder of BVH files into a cached training set
  render BVH...         draw clips as MP4 stick figures (and contact sheets)
  gallery FOLDER        render a few natural clips per content, with an index.json
  train FOLDER          train a model (moglow, rnn, vae, hvrnn, erd, quaternet) on a BVH folder
  sample CHECKPOINT     generate motion for control signals or labels (npz, BVH, optional MP4)
  natural FOLDER        export held-out natural clips the same way (the NAT system)
  evaluate CHECKPOINT   held-out loss (MoGlow: negative log-likelihood per frame)
  sliding CHECKPOINT    where a MoGlow's foot sliding arises, on held-out takes
  prepare-submission FOLDER --controls BUNDLE
                        another lab's BVH files as a submission for a study's exported controls
  import-stylegestures CHECKPOINT
                        a checkpoint of the authors' MoGlow code as a project checkpoint
  hvrnn-classifiers, hvrnn-denoiser, hvrnn-eval FOLDER, hvrnn-label FOLDER
                        HVRNN's classifiers, denoiser, evaluation and labelling (generation/cli/hvrnn.py)
"""

from __future__ import annotations

import argparse
import sys

from ..motion.bvh import BVHError
from . import check_data, data, hvrnn, models, render, stylegestures, submission

# Every command's parser, in the order --help lists the commands; each is written beside
# its command in its group's module (a group's add_commands adds all of its own).
PARSERS = (data.add_commands, check_data.add_commands, render.add_commands, models.add_train_parser,
           models.add_sample_parser, data.add_natural_parser, models.add_evaluate_parser, models.add_sliding_parser,
           submission.add_commands, stylegestures.add_commands, hvrnn.add_commands)


def parser() -> argparse.ArgumentParser:
    root = argparse.ArgumentParser(prog="python -m generation", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = root.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add_parser in PARSERS:
        add_parser(commands)
    return root


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        return args.run(args)
    # CheckpointError is a ValueError; OSError: a folder for a file; FloatingPointError: training diverged
    except (BVHError, ValueError, OSError, FloatingPointError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
