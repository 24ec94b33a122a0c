"""HVRNN's auxiliary commands of ``python -m generation``:

  hvrnn-classifiers FOLDER  train the action and style classifiers on half the training takes
  hvrnn-denoiser FOLDER     train the denoising autoencoder on the training takes
  hvrnn-eval FOLDER         classifier outputs of held-out, real and generated sequences
                            (then ``python -m analysis hvrnn-scores`` for Table 2 and Fig. 4)
  hvrnn-label FOLDER        the action and style the classifiers see in each clip (a CSV)

Torch-backed modules are imported inside the commands, so ``--help`` starts quickly.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from .common import add_unit_arguments, dataset_units


def add_commands(commands: argparse._SubParsersAction) -> None:
    """Add the group's commands to the ``generation`` command line's subparsers."""
    p = _training_parser(commands, "hvrnn-classifiers", classifiers_command,
                         "train HVRNN's action and style classifiers",
                         "Train the attribute classifiers (Conv1D x3, pooling, linear) on the classifier half of "
                         "the training takes; report held-out accuracy.")
    p.add_argument("--channels", type=int, nargs=3, metavar="C",
                   help="output channels of the three convolutions (default: the configuration's)")
    _training_parser(commands, "hvrnn-denoiser", denoiser_command, "train HVRNN's denoising autoencoder",
                     "Train the denoising autoencoder on the training takes; report the held-out error of "
                     "corrupted and denoised data.")

    p = commands.add_parser("hvrnn-eval", help="classifier outputs for HVRNN's Table 2 and Fig. 4",
                            description="Run the attribute classifiers on the held-out sequences (the reference), "
                                        "the other half of the training takes (real) and sequences each checkpoint "
                                        "generates for the held-out labels and lengths; write them to an .npz for "
                                        "'python -m analysis hvrnn-scores'.")
    _data_arguments(p)
    p.add_argument("--classifiers", required=True, help="attribute classifiers' file (hvrnn-classifiers)")
    p.add_argument("--checkpoint", action="append", default=[], metavar="NAME=PATH",
                   help="a model to evaluate under a name (repeatable)")
    p.add_argument("--temperature", type=float, default=1.0)
    p.add_argument("--out", "-o", required=True, help="output file (.npz)")
    p.set_defaults(run=eval_command)

    p = commands.add_parser("hvrnn-label", help="label clips with the attribute classifiers",
                            description="Write the action and style the attribute classifiers see in every clip of a "
                                        "BVH folder (labelled or not; side-file labels are listed beside them) to a "
                                        "CSV, as HVRNN labels unlabelled data. The clips must share the skeleton "
                                        "the classifiers were trained on.")
    p.add_argument("folder", help="folder of .bvh files")
    p.add_argument("--classifiers", required=True, help="attribute classifiers' file (hvrnn-classifiers)")
    p.add_argument("--cache-dir", help="dataset cache folder")
    p.add_argument("--threads", type=int, help="CPU threads for torch")
    p.add_argument("--out", "-o", required=True, help="output file (.csv)")
    add_unit_arguments(p)
    p.set_defaults(run=label_command)


def _training_parser(commands, name: str, run, help: str, description: str) -> argparse.ArgumentParser:
    p = commands.add_parser(name, help=help, description=description)
    _data_arguments(p)
    p.add_argument("--out", "-o", required=True, help="output file (.safetensors)")
    p.add_argument("--steps", type=int, help="training steps (default: the configuration's)")
    p.set_defaults(run=run)
    return p


def _data_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("folder", help="folder of labelled .bvh files")
    p.add_argument("--cache-dir", help="dataset cache folder")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, help="CPU threads for torch")
    add_unit_arguments(p)


def _load(args: argparse.Namespace):
    import torch

    from ..hvrnn.data import load_attribute_data

    if args.threads:
        torch.set_num_threads(args.threads)
    return load_attribute_data(args.folder, cache_dir=args.cache_dir, **dataset_units(args))


def classifiers_command(args: argparse.Namespace) -> int:
    from ..hvrnn.classifiers import ClassifierConfig, accuracy, train_classifiers

    data = _load(args)
    changes = {"steps": args.steps, "channels": tuple(args.channels) if args.channels else None}
    config = dataclasses.replace(ClassifierConfig(), **{k: v for k, v in changes.items() if v is not None})
    start = time.perf_counter()
    classifiers, history = train_classifiers(data, config, seed=args.seed, progress=True)
    held_out = accuracy(classifiers, data.sequences("test"))
    metrics = {"test_accuracy": held_out, "part": "classifier", "seed": args.seed,
               "final_loss": {k: sum(v[-50:]) / len(v[-50:]) for k, v in history.items()},
               "seconds": round(time.perf_counter() - start, 1)}
    classifiers.save(args.out, data.dataset.fingerprint, metrics)
    chance = {"action": 1 / len(data.actions), "style": 1 / len(data.styles)}
    for kind, value in held_out.items():
        print(f"{kind}: held-out accuracy {value:.3f} (chance {chance[kind]:.3f}), {len(data.sequences('test'))} sequences")
    print(f"wrote {args.out}")
    return 0


def denoiser_command(args: argparse.Namespace) -> int:
    from ..hvrnn.denoiser import DenoiserConfig, denoising_errors, train_denoiser

    data = _load(args)
    config = DenoiserConfig() if args.steps is None else dataclasses.replace(DenoiserConfig(), steps=args.steps)
    start = time.perf_counter()
    denoiser, losses = train_denoiser(data, config, seed=args.seed, progress=True)
    errors = denoising_errors(denoiser, data.sequences("test"), seed=args.seed)
    denoiser.save(args.out, data.dataset.fingerprint, {"test_errors": errors, "seed": args.seed,
                                                       "final_loss": sum(losses[-50:]) / len(losses[-50:]),
                                                       "seconds": round(time.perf_counter() - start, 1)})
    print(f"held-out mean squared error (standardised): corrupted {errors['corrupted']:.4f}, "
          f"denoised {errors['denoised']:.4f}")
    print(f"wrote {args.out}")
    return 0


def eval_command(args: argparse.Namespace) -> int:
    from ..hvrnn.classifiers import AttributeClassifiers
    from ..hvrnn.evaluate import evaluation_outputs, save_outputs

    checkpoints = {}
    for item in args.checkpoint:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            raise ValueError(f"--checkpoint takes NAME=PATH, got {item!r}")
        if name in checkpoints:
            raise ValueError(f"--checkpoint name {name!r} given twice")
        checkpoints[name] = path
    data = _load(args)
    classifiers = AttributeClassifiers.load(args.classifiers)
    outputs = evaluation_outputs(data, classifiers, checkpoints, seed=args.seed, temperature=args.temperature)
    save_outputs(args.out, outputs, data)
    sizes = ', '.join(f"{name} ({len(values['action'])})" for name, values in outputs.items())
    print(f"wrote {args.out}: sets {sizes}")
    return 0


def label_command(args: argparse.Namespace) -> int:
    import csv
    import io

    import torch

    from ..files import write_atomic
    from ..hvrnn.classifiers import AttributeClassifiers
    from ..hvrnn.data import dataset_options
    from ..hvrnn.labelling import label_clips
    from ..motion.data.dataset import build_dataset

    if args.threads:
        torch.set_num_threads(args.threads)
    classifiers = AttributeClassifiers.load(args.classifiers)
    rows = label_clips(classifiers, build_dataset(args.folder, dataset_options(**dataset_units(args)), cache_dir=args.cache_dir))
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(args.out, table.getvalue().encode())
    labelled = [r for r in rows if r["content"] and r["style"]]
    print(f"wrote {args.out}: {len(rows)} clips, {len(rows) - len(labelled)} without labels")
    if labelled:
        agree = {kind: sum(r[f"predicted_{kind}"] == r[label] for r in labelled) / len(labelled)
                 for kind, label in (("action", "content"), ("style", "style"))}
        print(f"on the {len(labelled)} clips with labels the classifiers agree on the action in {agree['action']:.0%} "
              f"and the style in {agree['style']:.0%} (clips they were trained on included)")
    return 0
