"""Safetensors files for the networks that are not motion models (classifiers, denoiser).

Like ``generation.checkpoint``: the tensors, a JSON description under the header's
``motion_study_network`` key (what the network is, its configuration, what it was
trained on) and a digest of the tensors; written atomically, read without pickles,
refused with a message naming the file and the problem.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file

from ..checkpoint import CheckpointError, tensor_digest
from ..files import atomic_output

NETWORK_KEY = "motion_study_network"


def save_network(path: str | os.PathLike, module: torch.nn.Module, kind: str, description: dict) -> Path:
    """Write ``module``'s state and ``description`` (JSON-able) as a ``kind`` network."""
    path = Path(path)
    tensors = {k: v.detach().cpu().contiguous() for k, v in module.state_dict().items()}
    header = {NETWORK_KEY: json.dumps({"kind": kind, **description}), "digest": tensor_digest(tensors)}
    with atomic_output(path) as tmp:
        save_file(tensors, str(tmp), metadata=header)
    return path


def load_network(path: str | os.PathLike, kind: str) -> tuple[dict[str, torch.Tensor], dict]:
    """The tensors and description of a ``kind`` network file, checked."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such network file")
    try:
        with safe_open(str(path), framework="pt") as f:
            header = f.metadata() or {}
        tensors = load_file(str(path))
    except (SafetensorError, OSError, ValueError) as error:
        raise CheckpointError(f"{path}: not a readable safetensors file ({error})") from None
    if NETWORK_KEY not in header:
        raise CheckpointError(f"{path}: not a network file of this project (no '{NETWORK_KEY}' header)")
    try:
        description = json.loads(header[NETWORK_KEY])
    except json.JSONDecodeError as error:
        raise CheckpointError(f"{path}: the network's JSON header is invalid ({error.msg})") from None
    if description.get("kind") != kind:
        raise CheckpointError(f"{path}: holds a {description.get('kind')!r} network, not a {kind!r} one")
    if header.get("digest") != tensor_digest(tensors):
        raise CheckpointError(f"{path}: the tensors do not match the file's digest (the file was changed or damaged)")
    return tensors, description


def load_state(path: str | os.PathLike, module: torch.nn.Module, tensors: dict[str, torch.Tensor]) -> None:
    """Load ``tensors`` into ``module``, naming the file when they do not fit."""
    try:
        module.load_state_dict(tensors)
    except RuntimeError as error:
        raise CheckpointError(f"{path}: the tensors do not fit the network its description builds ({error})") from None
