"""Commands on models: ``train``, ``sample``, ``evaluate`` (the held-out loss) and ``sliding``
(where a MoGlow's foot sliding arises), each with its parser beside it.

Modules that import torch (train, generator, checkpoint) are imported by the commands
that need them, so that ``--help`` starts quickly.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from tqdm import tqdm

from measures.feet import choose_foot_joints
from measures.units import UNIT_NAMES, UNITS

from ..control import (PRESETS, following_arrays, length_warning, load_control_file, preset_path, shorter_than_asked,
                       take_paths)
from ..motion.bvh import motion_to_bvh, write_bvh
from ..motion.clip_files import LOCOMOTION, contents_or_all
from ..motion.dataset import build_dataset
from ..motion.dataset_options import DatasetOptions
from ..motion.npz import save_motion_npz
from ..motion.root import RootOptions, root_trajectory
from ..motion.takes import natural_takes
from ..registry import LABELS, MODELS, model_kind
from ..render import render_video
from .common import (add_camera_arguments, add_unit_arguments, camera_from, dataset_units, shown_control, take_names,
                     warn)


OWN_CONTROL = "own"  # --draw-control without a value: each clip's own control


def _dataset_for_training(args: argparse.Namespace, attributes: bool):
    """Path models: the locomotion windows by default; attribute models: every content's
    labelled angle sequences (``generation.hvrnn.data``)."""
    if attributes:
        from ..hvrnn.data import load_attribute_data

        contents = tuple(args.contents.split(",")) if args.contents else None
        return load_attribute_data(args.folder, contents, cache_dir=args.cache_dir, **dataset_units(args))
    options = DatasetOptions(contents=_contents(args), reverse=args.reverse, overlap=args.overlap, **dataset_units(args))
    dataset = build_dataset(args.folder, options, cache_dir=args.cache_dir)
    warn(dataset.window_warnings())
    dataset.require_training_windows()
    return dataset


def _contents(args: argparse.Namespace) -> tuple[str, ...] | None:
    """--contents, else the locomotion contents, or every clip of folders without labels."""
    if args.contents:
        return tuple(args.contents.split(","))
    contents = contents_or_all(args.folder, LOCOMOTION)
    if contents is None:
        print("note: the clips have no content labels: all of them are used, as one content")
    return contents


def train_command(args: argparse.Namespace) -> int:
    from ..train import TrainOptions, train

    _require_device(args.device)
    _use_threads(args)
    attributes = model_kind(args.model).control == LABELS
    for option in ("classifiers", "denoiser"):
        if getattr(args, option) and not attributes:
            raise ValueError(f"--{option} is for attribute-controlled models, not {args.model}")
    if args.rotation_output and args.model != "hvrnn":
        raise ValueError(f"--rotation-output is for HVRNN, not {args.model}")
    dataset = _dataset_for_training(args, attributes)
    if args.denoiser:  # HVRNN Sec. 3.1: the training data is cleaned before the model learns from it
        from ..hvrnn.denoiser import Denoiser, denoise_training_data

        denoiser = Denoiser.load(args.denoiser)
        if denoiser.feature_dim != dataset.feature_dim:
            raise ValueError(f"{args.denoiser}: the denoiser reads {denoiser.feature_dim} features per frame, "
                             f"this data has {dataset.feature_dim}")
        dataset = denoise_training_data(dataset, denoiser)
    options = TrainOptions(steps=args.steps, eval_every=args.eval_every, seed=args.seed, device=args.device)
    overrides = {name: value for name, value in (("classifiers", args.classifiers),
                                                 ("rotation_output", args.rotation_output)) if value}
    overrides.update(args.settings)
    meta = train(args.model, args.preset, dataset, args.out, options, resume=args.resume, overrides=overrides or None)
    last = meta.metrics["history"][-1]
    print(f"{args.out}: step {meta.step}, held-out loss {last['val_loss']:.4f}, "
          f"training loss {last['train_loss']:.4f}, {last['seconds']:.0f} s of training")
    return 0


def add_train_parser(commands: argparse._SubParsersAction) -> None:
    """The ``train`` command's parser."""
    p = commands.add_parser("train", help="train a model on a BVH folder",
                            description="Train a model on the locomotion clips of FOLDER (held-out takes for "
                                        "validation). Writes CHECKPOINT (safetensors + JSON header) at every evaluation; "
                                        "--resume continues from it.")
    p.add_argument("folder", nargs="+", help="folder of .bvh files; several are pooled (clip names must differ)")
    p.add_argument("--model", "--kind", choices=tuple(MODELS), default="moglow", help="model kind (default %(default)s)")
    p.add_argument("--preset", default="cpu", help="configuration preset: cpu, paper, or with an ablation such as cpu-MG-D or cpu-SL (default %(default)s)")
    p.add_argument("--classifiers", help="attribute classifiers' file for HVRNN's classifier loss")
    p.add_argument("--rotation-output", help="HVRNN: what its decoder outputs per joint: quaternion (default), matrix "
                                             "(6-D, Gram-Schmidt) or axis_angle (a rotation vector)")
    p.add_argument("--denoiser", help="attribute models: a denoiser (hvrnn-denoiser) that cleans the training "
                                      "takes first, as HVRNN's paper does; the checkpoint's data fingerprint records it")
    p.add_argument("--out", "-o", required=True, help="checkpoint path (.safetensors)")
    p.add_argument("--steps", type=int, default=4000, help="total training steps (default %(default)s)")
    p.add_argument("--eval-every", type=int, default=250, help="steps between validation and checkpoint (default %(default)s)")
    p.add_argument("--resume", action="store_true", help="continue from the checkpoint at --out")
    p.add_argument("--set", action="append", type=_setting, default=[], metavar="NAME=VALUE", dest="settings",
                   help="replace one field of the preset's model configuration (e.g. dropout=0.7) or training "
                        "knobs (learning_rate, warmup_steps, grad_clip, batch_size); repeatable. With --resume "
                        "it applies from the checkpoint's step on, and the checkpoint records the change")
    p.add_argument("--contents", help="content labels to train on (default: locomotion for path models, all for "
                                      "attribute models; every clip where the clips have no labels)")
    p.add_argument("--reverse", action="store_true", help="path models: also train on the training takes played backwards "
                   "(as the MoGlow authors' locomotion set-up does; held-out takes are never augmented)")
    p.add_argument("--overlap", type=float, default=0.5, help="path models: overlap of consecutive 4-s training "
                   "windows; short takes give more windows with more overlap (default %(default)s)")
    p.add_argument("--cache-dir", help="dataset cache folder")
    p.add_argument("--device", default="cpu", help="cpu or cuda (default %(default)s)")
    p.add_argument("--threads", type=_thread_count, help="CPU threads for torch (default: torch's own choice)")
    p.add_argument("--seed", type=int, default=0)
    add_unit_arguments(p)
    p.set_defaults(run=train_command)


def _require_device(device: str) -> None:
    """Refuse --device cuda up front where torch has no GPU, instead of a traceback from deep in torch."""
    import torch

    if device.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError("--device cuda asked for, but torch sees no CUDA device (is a CUDA build of torch installed?)")


def _setting(text: str) -> tuple[str, object]:
    """NAME=VALUE, the value read as JSON where it is JSON (numbers, true/false), else as text."""
    name, equals, value = text.partition("=")
    if not equals or not name.strip():
        raise argparse.ArgumentTypeError(f"'{text}' is not NAME=VALUE")
    try:
        return name.strip(), json.loads(value)
    except json.JSONDecodeError:
        return name.strip(), value


def _controls(args: argparse.Namespace, dataset_options: dict):
    if args.takes and "held-out" not in args.control:
        raise ValueError("--takes names the takes of held-out control: add -c held-out")
    fps = dataset_options["fps"]
    controls = []
    for name in args.control:
        if name == "held-out":
            folder = args.data or os.environ.get("MOTION_DATA")
            if not folder:
                raise ValueError("held-out control needs the motion folder: --data FOLDER or $MOTION_DATA")
            takes, _ = natural_takes(folder, DatasetOptions.from_dict(dataset_options), args.takes, progress=True)
            held_out = take_paths([(take.name, take.control) for take in takes], fps, args.seconds, args.lead_in)
            if not held_out:
                raise ValueError(f"no held-out take is longer than the lead-in of {args.lead_in:g} s")
            warn([length_warning(c, args.seconds) for c in shorter_than_asked(held_out, args.seconds)])
            controls += held_out
        elif name in PRESETS:
            controls.append(preset_path(name, fps))
        else:
            controls += load_control_file(name, fps)
    return controls


def _use_threads(args: argparse.Namespace) -> None:
    """torch's CPU threads, where --threads gives them."""
    import torch

    if args.threads:
        torch.set_num_threads(args.threads)


def _thread_count(text: str) -> int:
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise argparse.ArgumentTypeError(f"threads must be a whole number of at least 1, got {text!r}")
    return count


def sample_command(args: argparse.Namespace) -> int:
    from ..generator import Generator
    from ..models.precision import cpu_has_bfloat16_units

    _use_threads(args)
    generator = Generator.load(args.checkpoint, args.device)
    if generator.attributes:
        if args.draw_control:
            raise ValueError(f"--draw-control draws a path; {args.checkpoint} follows action and style labels")
        return _sample_attributes(args, generator)
    if args.action or args.style:
        raise ValueError(f"--action and --style are for attribute-controlled models; {args.checkpoint} follows a path (--control)")
    dataset_options = DatasetOptions.from_dict(generator.meta.features["dataset_options"])
    controls = _controls(args, generator.meta.features["dataset_options"])
    shown = None if args.draw_control in (None, OWN_CONTROL) else shown_control(args.draw_control, generator.fps)
    for control in controls if shown is not None else ():
        if control.n_frames != shown.n_frames:
            raise ValueError(f"--draw-control {args.draw_control} lasts {shown.n_frames} frames, the control "
                             f"{control.name} {control.n_frames}: a clip is drawn over a control of its own length")
    precision = generator.resolve_precision(args.precision)
    print(f"sampling in {precision}" + (" (--precision auto)" if args.precision == "auto" else ""), file=sys.stderr)
    if precision == "bfloat16" and generator.device.type == "cpu" and not cpu_has_bfloat16_units():
        print("warning: this CPU has no bfloat16 units (AVX512-BF16 or AMX); torch emulates them, "
              "so --precision bfloat16 samples far slower than float32 here", file=sys.stderr)
    out = Path(args.out)
    for control in tqdm(controls, desc="sampling", unit="control", disable=len(controls) < 2):
        motions = generator.sample(control, n=args.n, seed=args.seed, temperature=args.temperature,
                                   warmup_seconds=args.warmup_seconds, precision=precision)
        path = control.path()
        for i, motion in enumerate(motions):
            stem = f"{control.name}_{i:02d}"
            save_motion_npz(motion, out / f"{stem}.npz", control=control.velocities, floor_path=path.xz,
                            **following_arrays(motion, path, dataset_options.root))
            write_bvh(motion_to_bvh(motion, unit=args.bvh_unit), out / f"{stem}.bvh")
            if args.draw_control:  # the figure's own path over the control's
                drawn = shown or control
                render_video(motion, out / f"{stem}.mp4", camera=camera_from(args), size=args.size,
                             root_path=root_trajectory(motion, dataset_options.root).xz,
                             control_path=drawn.path().xz)
            elif args.render:
                render_video(motion, out / f"{stem}.mp4", camera=camera_from(args), size=args.size, root_path=path.xz)
    print(f"{len(controls) * args.n} clips in {out} ({_written_units(args.bvh_unit)})")
    _note_training_unit(generator, args.bvh_unit)
    return 0


def _sample_attributes(args: argparse.Namespace, generator) -> int:
    """N clips of --seconds for every --action and --style pair (default: all the model knows)."""
    from ..control import AttributeControl

    model = generator.model
    actions, styles = args.action or list(model.actions), args.style or list(model.styles)
    frames = max(1, int(round(args.seconds * generator.fps)))
    out = Path(args.out)
    pairs = [(a, s) for a in actions for s in styles]
    for action, style in tqdm(pairs, desc="sampling", unit="label pair", disable=len(pairs) < 2):
        control = AttributeControl(action, style, frames, generator.fps, f"{action}_{style}")
        for i, motion in enumerate(generator.sample(control, n=args.n, seed=args.seed, temperature=args.temperature)):
            stem = f"{control.name}_{i:02d}"
            floor = root_trajectory(motion, RootOptions()).xz
            save_motion_npz(motion, out / f"{stem}.npz", floor_path=floor)
            write_bvh(motion_to_bvh(motion, unit=args.bvh_unit), out / f"{stem}.bvh")
            if args.render:
                render_video(motion, out / f"{stem}.mp4", camera=camera_from(args), size=args.size, root_path=floor)
    print(f"{len(pairs) * args.n} clips in {out} ({_written_units(args.bvh_unit)})")
    _note_training_unit(generator, args.bvh_unit)
    return 0


def _written_units(bvh_unit: str) -> str:
    # BVH has no field for its unit: the command line is where a user learns it.
    return f"BVH lengths in {UNIT_NAMES[bvh_unit]}, npz in centimetres; y up"


def _note_training_unit(generator, bvh_unit: str) -> None:
    """Say so when the model learnt from files in another known unit than the BVH is
    written in: a user comparing the samples with those files needs that unit."""
    scale = generator.meta.features["dataset_options"].get("scale")
    trained = next((unit for unit, factor in UNITS.items() if scale is not None and math.isclose(scale, factor)), None)
    if trained not in (None, bvh_unit):
        print(f"note: the model learnt from BVH files in {UNIT_NAMES[trained]}; --bvh-unit {trained} writes "
              "the samples in that unit", file=sys.stderr)


def add_sample_parser(commands: argparse._SubParsersAction) -> None:
    """The ``sample`` command's parser."""
    p = commands.add_parser("sample", help="generate motion for control signals",
                            description="Sample N motions per control signal. CONTROL is a preset name "
                                        "(walk-straight, walk-circle, sidestep-left, walk-backward, stand-still, speed-ramp, ...), "
                                        "a JSON or YAML path description, or 'held-out' for the held-out natural clips.")
    p.add_argument("checkpoint", help="a checkpoint written by train")
    p.add_argument("--control", "-c", nargs="+", default=["walk-straight"], help="control presets, files or 'held-out'")
    p.add_argument("--action", nargs="+", help="attribute models: actions to sample (default: all the model knows)")
    p.add_argument("--style", nargs="+", help="attribute models: styles to sample (default: all the model knows)")
    p.add_argument("--out", "-o", required=True,
                   help="output folder: per clip an npz (the model's joint positions) and a BVH (the root's "
                        "position and every joint's ZXY rotation on the training rig; path models' rotations "
                        "come from their positions by inverse kinematics)")
    p.add_argument("--n", type=int, default=1, help="samples per control (default %(default)s)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--temperature", type=float, default=1.0, help="sampling temperature (default %(default)s)")
    p.add_argument("--warmup-seconds", type=float,
                   help="path models: motion generated before the kept clip and discarded, holding the first "
                        "control frame (default: 1 s for MoGlow, as in its paper; 0 for the baselines)")
    # generation.models.precision.PRECISIONS, spelt out so that building the parser imports no torch
    p.add_argument("--precision", choices=("auto", "float32", "bfloat16", "int8"), default="auto",
                   help="how MoGlow's coupling networks multiply: auto is bfloat16 on CPUs with bfloat16 units "
                        "(AVX512-BF16 or AMX), float32 elsewhere; int8 (x86 CPUs) is faster still but further "
                        "from float32's samples (default %(default)s)")
    p.add_argument("--seconds", type=float, default=4.0, help="length of held-out control or of attribute-controlled clips (default %(default)s)")
    p.add_argument("--data", nargs="+", help="motion folder(s) for held-out control (default $MOTION_DATA)")
    p.add_argument("--takes", type=take_names, metavar="NAME,...",
                   help="held-out control from these takes of the folder (file names without .bvh), instead of "
                        "the takes the training's seeded split holds out")
    p.add_argument("--lead-in", type=float, default=0.0, metavar="SECONDS",
                   help="held-out control starts SECONDS into each take, and the warm-up runs on the take's own "
                        "control before it, as the MoGlow authors' code samples a test take from its start "
                        "(default %(default)s: the control starts with the take, and the warm-up holds its first "
                        "frame); export NAT with the same `natural --lead-in`")
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=_thread_count, help="CPU threads for torch (default: torch's own choice)")
    p.add_argument("--render", action="store_true", help="also render each clip to MP4")
    p.add_argument("--draw-control", nargs="?", const=OWN_CONTROL, metavar="CONTROL",
                   help="render each clip (implies --render) with a control's path drawn on the floor and the "
                        "camera following that path, the figure's own path over it: without a value each "
                        "clip's own control; with a preset name or a JSON or YAML file describing one path, "
                        "that path under every clip, as an appropriateness study shows a clip sampled for "
                        "another control (it must last as many frames as the clips)")
    p.add_argument("--bvh-unit", choices=tuple(UNITS), default="cm",
                   help="length unit of the BVH files written (BVH cannot state it; the command prints it); "
                        "npz files are always in cm (default %(default)s)")
    add_camera_arguments(p)
    p.set_defaults(run=sample_command)


def evaluate_command(args: argparse.Namespace) -> int:
    from ..checkpoint import load_checkpoint
    from ..models.attribute import AttributeModel
    from ..train import attribute_tensors, evaluate_loss, tensors

    model, meta = load_checkpoint(args.checkpoint, args.device)
    if meta.features.get("control_layout"):
        raise ValueError(f"{args.checkpoint} reads control in the {meta.features['control_layout']} layout, which "
                         "the held-out data here is not in; evaluate it with the code it came from")
    folder = args.data or os.environ.get("MOTION_DATA")
    if not folder:
        raise ValueError("evaluation needs the motion folder: --data FOLDER or $MOTION_DATA")
    options = DatasetOptions.from_dict(meta.features["dataset_options"])
    dataset = build_dataset(folder, options, cache_dir=args.cache_dir)
    if dataset.fingerprint != meta.data_fingerprint:
        print("warning: this data differs from the data the model was trained on", file=sys.stderr)
    if isinstance(model, AttributeModel):
        from ..hvrnn.data import AttributeData

        data = attribute_tensors(AttributeData.from_dataset(dataset, options.seed), "test", model.standardization, args.device)
    else:
        data = tensors(dataset, "test", args.device)
    loss = evaluate_loss(model, data)
    name = "negative log-likelihood (nats per frame)" if meta.kind == "moglow" else "loss"
    if not math.isfinite(loss):
        raise ValueError(f"{args.checkpoint}: the held-out {name} is {loss}: the model's outputs overflow on this data")
    print(f"{args.checkpoint}: held-out {name}: {loss:.4f} over {len(dataset.select('test'))} held-out takes")
    return 0


def add_evaluate_parser(commands: argparse._SubParsersAction) -> None:
    """The ``evaluate`` command's parser."""
    p = commands.add_parser("evaluate", help="held-out loss of a checkpoint")
    p.add_argument("checkpoint")
    p.add_argument("--data", nargs="+", help="motion folder(s) (default $MOTION_DATA)")
    p.add_argument("--cache-dir", help="dataset cache folder")
    p.add_argument("--device", default="cpu")
    p.set_defaults(run=evaluate_command)


def sliding_command(args: argparse.Namespace) -> int:
    from ..generator import Generator
    from ..motion.features import decode_positions
    from ..sliding import SETTLE_SECONDS, sliding_ladder

    _require_device(args.device)
    generator = Generator.load(args.checkpoint, args.device)
    meta = generator.meta
    if meta.kind != "moglow" or meta.features.get("control_layout"):
        raise ValueError(f"{args.checkpoint} is not a MoGlow of this project ({meta.kind}"
                         f"{', imported' if meta.features.get('control_layout') else ''}): the measurement predicts "
                         "each frame from a true past, which needs MoGlow's conditioning on past poses")
    if args.takes < 1 or args.samples < 1 or args.seconds <= 0:
        raise ValueError(f"--takes and --samples must be at least 1 and --seconds positive, not {args.takes}, "
                         f"{args.samples} and {args.seconds:g}")
    folder = args.data or os.environ.get("MOTION_DATA")
    if not folder:
        raise ValueError("the measurement needs the motion folder: --data FOLDER or $MOTION_DATA")
    dataset = build_dataset(folder, DatasetOptions.from_dict(meta.features["dataset_options"]), cache_dir=args.cache_dir)
    if dataset.fingerprint != meta.data_fingerprint:
        print("warning: this data differs from the data the model was trained on", file=sys.stderr)
    contents = tuple(c.strip() for c in args.contents.split(","))
    clips = [c for c in dataset.select("test", augmented=False) if c.content in contents][: args.takes]
    if not clips:
        raise ValueError(f"no held-out take of {', '.join(contents)} in the data")
    frames = int(round(args.seconds * generator.fps))
    takes = [(arrays["pose"][:frames].astype("float64"), arrays["control"][:frames].astype("float64"))
             for arrays in map(dataset.clip_arrays, clips)]
    skeleton = generator.skeleton
    feet = choose_foot_joints(skeleton.names, skeleton.parents,
                              [decode_positions(pose, control, generator.fps) for pose, control in takes], "toe")
    table = sliding_ladder(generator, takes, feet, args.samples, args.seed)
    print(f"lower-foot speed ({', '.join(skeleton.names[i] for i in feet)}) of {len(takes)} held-out "
          f"{'/'.join(contents)} take(s) on their own control, from {SETTLE_SECONDS:g} s to {args.seconds:g} s at most:")
    for row in table.itertuples():
        print(f"  {row.condition:<28} {row.lower_foot_speed:6.1f} cm/s  ({row.clips} clips)")
    return 0


def add_sliding_parser(commands: argparse._SubParsersAction) -> None:
    """The ``sliding`` command's parser."""
    p = commands.add_parser("sliding", help="where a MoGlow's foot sliding arises, on held-out takes",
                            description="The weight-bearing foot's speed on held-out takes of CONTENTS, on each "
                                        "take's own control, from 1 s in: the take itself; each frame predicted "
                                        "one frame ahead of the take's true past at temperature 0; free-running "
                                        "samples from the take's first poses at temperature 0 and 1, from the "
                                        "mean pose (as the authors' code samples), and from the mean pose after "
                                        "sample's warm-up (generation/sliding.py).")
    p.add_argument("checkpoint", help="a MoGlow checkpoint")
    p.add_argument("--data", nargs="+", help="motion folder(s) the model learnt from (default $MOTION_DATA)")
    p.add_argument("--contents", default="walk", help="content labels of the takes (default %(default)s)")
    p.add_argument("--takes", type=int, default=12, help="how many held-out takes, at most (default %(default)s)")
    p.add_argument("--seconds", type=float, default=6.0, help="of each take, at most (default %(default)s)")
    p.add_argument("--samples", type=int, default=8, help="samples per take at T=1 (default %(default)s)")
    p.add_argument("--seed", type=int, default=1, help="of the free-running samples (default %(default)s)")
    p.add_argument("--cache-dir", help="dataset cache folder")
    p.add_argument("--device", default="cpu",
                   help="cpu or cuda: where the model predicts and samples; a paper-sized MoGlow wants a GPU "
                        "(default %(default)s)")
    p.set_defaults(run=sliding_command)
