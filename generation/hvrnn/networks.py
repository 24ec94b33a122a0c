"""Files of the networks that are not motion models (classifiers, denoiser).

Stored as ``generation.checkpoints.store`` stores checkpoints: the tensors, a JSON description under
the header's ``motion_study_network`` key (what the network is, its configuration, what
it was trained on) and a digest of the tensors; written atomically, read without
pickles, refused with a message naming the file and the problem.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import torch

from ..checkpoints.store import CheckpointError, read_tensors, write_tensors

NETWORK_KEY = "motion_study_network"


def save_network(path: str | os.PathLike, module: torch.nn.Module, kind: str, description: dict) -> Path:
    """Write ``module``'s state and ``description`` (JSON-able) as a ``kind`` network."""
    return write_tensors(path, module.state_dict(), {NETWORK_KEY: json.dumps({"kind": kind, **description})})


def load_network(path: str | os.PathLike, kind: str) -> tuple[dict[str, torch.Tensor], dict]:
    """The tensors and description of a ``kind`` network file, checked."""
    path = Path(path)
    tensors, header = read_tensors(path, "network")
    if NETWORK_KEY not in header:
        raise CheckpointError(f"{path}: not a network file of this project (no '{NETWORK_KEY}' header)")
    try:
        description = json.loads(header[NETWORK_KEY])
    except json.JSONDecodeError as error:
        raise CheckpointError(f"{path}: the network's JSON header is invalid ({error.msg})") from None
    if not isinstance(description, dict):
        raise CheckpointError(f"{path}: the network's JSON header is not an object")
    if description.get("kind") != kind:
        raise CheckpointError(f"{path}: holds a {description.get('kind')!r} network, not a {kind!r} one")
    return tensors, description


def load_state(path: str | os.PathLike, module: torch.nn.Module, tensors: dict[str, torch.Tensor]) -> None:
    """Load ``tensors`` into ``module``, naming the file when they do not fit."""
    try:
        module.load_state_dict(tensors)
    except RuntimeError as error:
        raise CheckpointError(f"{path}: the tensors do not fit the network its description builds ({error})") from None
