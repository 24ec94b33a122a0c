"""What a checkpoint must satisfy before a model is built from it or sampled.

Researchers upload checkpoints to the study app, so a checkpoint is input like any other
and may describe anything. Three checks, cheapest first, each naming the field or tensor:

- ``check_description``: the JSON half: a positive, finite frame rate, standardisation
  statistics that are finite and as long as the model's features, a skeleton with joints;
- ``build_within``: the model the hyperparameters describe is built under a budget of
  the tensors the file holds: every allocation is checked before it is made, so a 7 KB
  file claiming a model of billions of parameters is refused in milliseconds, having
  allocated nothing; the model built must then have exactly the file's tensor names,
  shapes and dtypes;
- ``check_values``: every floating-point tensor finite (NaN weights cannot sample).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import torch
from torch.overrides import TorchFunctionMode

from .motion.dataset import DatasetOptions
from .motion.types import Skeleton


class CheckpointError(ValueError):
    """A checkpoint that cannot be used; the message names the file and the problem."""


def _numbers(values: object) -> list[float] | None:
    if not isinstance(values, list) or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return None
    return [float(v) for v in values]


def check_description(path: Path, kind_needs_control: bool, pose_dim: int, control_dim: int,
                      features: dict, stats: dict, skeleton: dict) -> None:
    """The checkpoint's JSON fields make sense together (see the module docstring)."""
    try:
        DatasetOptions.from_dict(features["dataset_options"])
    except KeyError:
        raise CheckpointError(f"{path}: features.dataset_options is missing") from None
    except (TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: features.dataset_options: {error}") from None
    expected = {"pose": pose_dim, **({"control": control_dim} if kind_needs_control else {})}
    for name, size in expected.items():
        if not isinstance(stats.get(name), dict):
            raise CheckpointError(f"{path}: stats.{name} is missing (the standardisation of the {name} features)")
        for field in ("mean", "std"):
            values = _numbers(stats[name].get(field))
            if values is None:
                raise CheckpointError(f"{path}: stats.{name}.{field} must be a list of numbers")
            if len(values) != size:
                raise CheckpointError(f"{path}: stats.{name}.{field} has {len(values)} values; the model's "
                                      f"{name} features have {size}")
            if not all(math.isfinite(v) for v in values):
                raise CheckpointError(f"{path}: stats.{name}.{field} holds NaN or infinity")
            if field == "std" and min(values) <= 0:
                raise CheckpointError(f"{path}: stats.{name}.std must be positive, holds {min(values):g}")
    if not skeleton.get("names"):
        raise CheckpointError(f"{path}: skeleton has no joints")
    try:
        joints = Skeleton.from_dict(skeleton)
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: skeleton: {type(error).__name__}: {error}") from None
    if not torch.isfinite(torch.as_tensor(joints.offsets)).all():
        raise CheckpointError(f"{path}: skeleton offsets hold NaN or infinity")


# Buffers a model keeps out of its file (masks, signs) and scratch tensors made while it is
# built (a random matrix to decompose) are small beside its weights.
UNSTORED_ELEMENTS = 1_000_000
# The functions that allocate a new tensor from a size; a model's weights and buffers are
# made by these (nn.Linear, nn.LSTM, nn.Embedding: torch.empty).
_FACTORIES = {torch.empty, torch.zeros, torch.ones, torch.rand, torch.randn, torch.full, torch.eye}


def _elements_asked(func, args: tuple, kwargs: dict) -> int:
    if func is torch.eye:
        rows = args[0] if args else kwargs.get("n", 0)
        columns = args[1] if len(args) > 1 and isinstance(args[1], int) else kwargs.get("m", rows)
        return int(rows) * int(columns)
    first = kwargs.get("size", args[0] if args else ())
    dims = first if isinstance(first, tuple | list | torch.Size) else [a for a in args if isinstance(a, int)]
    return math.prod(int(d) for d in dims)


class _Budget(TorchFunctionMode):
    """Refuses, before it is made, any allocation past the budget of values, and any
    parameter past the budget of tensors; the message names the file and the tensor."""

    def __init__(self, path: Path, tensors: int, elements: int) -> None:
        super().__init__()
        self.path, self.tensors, self.elements = path, tensors, elements + UNSTORED_ELEMENTS
        self.made = {"parameters": 0, "elements": 0}

    def refuse(self, what: str) -> None:
        raise CheckpointError(f"{self.path}: the hyperparameters describe a model larger than the file's "
                              f"{self.tensors} tensors of {self.elements - UNSTORED_ELEMENTS:,} values ({what})")

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        if func in _FACTORIES:
            asked = _elements_asked(func, args, kwargs)
            if self.made["elements"] + asked > self.elements:
                self.refuse(f"{func.__name__} of {asked:,} values asked for")
            self.made["elements"] += asked
        return func(*args, **kwargs)

    def parameter(self, module, name: str, value) -> None:
        self.made["parameters"] += value is not None
        if self.made["parameters"] > self.tensors:
            self.refuse(f"parameter {name!r} is one too many")


def build_within(path: Path, build: Callable[[], torch.nn.Module],
                 stored: Mapping[str, tuple[tuple[int, ...], torch.dtype | None]]) -> torch.nn.Module:
    """``build()``, the model of the hyperparameters, within the budget of the ``stored``
    tensors ({name: (shape, dtype)} from the file's header), checked to have exactly them."""
    budget = _Budget(path, len(stored), sum(math.prod(shape) for shape, _ in stored.values()))
    hook = torch.nn.modules.module.register_module_parameter_registration_hook(budget.parameter)
    try:
        with budget:
            model = build()
    except CheckpointError:
        raise
    except (KeyError, TypeError, ValueError, RuntimeError) as error:  # a header that builds no model
        raise CheckpointError(f"{path}: the hyperparameters do not build a model ({type(error).__name__}: {error})") from None
    finally:
        hook.remove()
    expected = model.state_dict()
    missing = sorted(set(expected) - set(stored))
    unexpected = sorted(set(stored) - set(expected))
    if missing or unexpected:
        problems = ([f"missing tensor(s) {', '.join(missing[:5])}"] if missing else []) + (
            [f"unexpected tensor(s) {', '.join(unexpected[:5])}"] if unexpected else [])
        raise CheckpointError(f"{path}: does not fit the model its hyperparameters describe: {'; '.join(problems)}")
    for name, (shape, dtype) in stored.items():
        if tuple(shape) != tuple(expected[name].shape):
            raise CheckpointError(
                f"{path}: tensor {name} has shape {tuple(shape)}, the model needs {tuple(expected[name].shape)}")
        if dtype != expected[name].dtype:
            raise CheckpointError(f"{path}: tensor {name} is {str(dtype).removeprefix('torch.')}, the model needs "
                                  f"{str(expected[name].dtype).removeprefix('torch.')} (a cast would change its values)")
    return model


def check_values(path: Path, tensors: Mapping[str, torch.Tensor]) -> None:
    """Every floating-point tensor finite."""
    for name, tensor in tensors.items():
        if tensor.is_floating_point() and not torch.isfinite(tensor).all():
            bad = int((~torch.isfinite(tensor)).sum())
            raise CheckpointError(f"{path}: tensor {name} holds {bad} NaN or infinite value(s)")
