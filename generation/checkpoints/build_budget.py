"""Building a model within the budget of the tensors its file holds.

A checkpoint's hyperparameters may describe any model; the file's header says how many
tensors of how many values it holds. ``build_within`` builds the model under that
budget, checking every allocation before it is made, so a 7 KB file claiming billions of
parameters is refused in milliseconds having allocated nothing; the model built must
then have exactly the file's tensor names, shapes and dtypes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import torch
from torch.overrides import TorchFunctionMode

from .store import CheckpointError

# safetensors' dtype names, for comparing a file's header with a model before loading it.
SAFETENSORS_DTYPES = {"F64": torch.float64, "F32": torch.float32, "F16": torch.float16, "BF16": torch.bfloat16,
                      "I64": torch.int64, "I32": torch.int32, "I16": torch.int16, "I8": torch.int8,
                      "U8": torch.uint8, "BOOL": torch.bool}

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
                 stored: Mapping[str, tuple[tuple[int, ...], str]]) -> torch.nn.Module:
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
    for name, (shape, stored_dtype) in stored.items():
        dtype = SAFETENSORS_DTYPES.get(stored_dtype, stored_dtype)
        if tuple(shape) != tuple(expected[name].shape):
            raise CheckpointError(
                f"{path}: tensor {name} has shape {tuple(shape)}, the model needs {tuple(expected[name].shape)}")
        if dtype != expected[name].dtype:
            raise CheckpointError(f"{path}: tensor {name} is {str(dtype).removeprefix('torch.')}, the model needs "
                                  f"{str(expected[name].dtype).removeprefix('torch.')} (a cast would change its values)")
    return model
