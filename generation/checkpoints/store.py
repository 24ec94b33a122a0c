"""Safetensors files of this project: tensors, a JSON description in the header, a digest.

Model checkpoints (``generation.checkpoints.checkpoint``) and HVRNN's auxiliary networks
(classifiers, denoiser) are both stored this way: the tensors, string metadata in the
header and, under ``digest``, a SHA-256 of the tensors' names and bytes. Files are
written atomically and read without pickles; a file that is missing, unreadable, whose
tensors do not match its digest or hold NaN or infinity is refused with a
``CheckpointError`` naming the file and the problem (and the tensor).

Reading a header needs no torch, so the web app can list checkpoints cheaply; torch is
imported only where tensors are read or written. ``keep`` stores a file that came from
elsewhere (the study app's uploads) in a folder under its content digest: the SHA-256
of its header, which holds its description and its tensors' digest, so the same tensors
described otherwise are another file.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from safetensors import SafetensorError, safe_open

from ..files import atomic_output

if TYPE_CHECKING:
    import torch

DIGEST_KEY = "digest"
SUFFIX = ".safetensors"
# A SHA-256 as the store writes it (file names, digests): what a name must look like before
# it becomes part of a path.
SHA256_HEX = re.compile(r"[0-9a-f]{64}")


class CheckpointError(ValueError):
    """A checkpoint that cannot be used; the message names the file and the problem."""


def tensor_digest(tensors: Mapping[str, torch.Tensor]) -> str:
    """SHA-256 of the tensors' names and bytes, in name order."""
    digest = hashlib.sha256()
    for name in sorted(tensors):
        digest.update(name.encode())
        digest.update(tensors[name].detach().cpu().contiguous().numpy().tobytes())
    return digest.hexdigest()


def write_tensors(path: str | os.PathLike, state: Mapping[str, Any], header: dict[str, str],
                  digest: bool = True) -> Path:
    """Write ``state`` (tensors, or values torch turns into tensors) and ``header``
    atomically; with ``digest`` the header also records the tensors' digest."""
    import torch
    from safetensors.torch import save_file

    path = Path(path)
    tensors = {name: torch.as_tensor(value).detach().cpu().contiguous() for name, value in state.items()}
    header = {**header, DIGEST_KEY: tensor_digest(tensors)} if digest else header
    with atomic_output(path) as tmp:
        save_file(tensors, str(tmp), metadata=header)
    return path


def read_header(path: str | os.PathLike, what: str = "checkpoint") -> dict[str, str]:
    """The header metadata of a safetensors file (the tensors are not read); ``what``
    names the kind of file in messages."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such {what} file")
    try:
        with safe_open(str(path), framework="numpy") as f:
            return f.metadata() or {}
    except (SafetensorError, OSError, ValueError) as error:
        raise CheckpointError(f"{path}: not a readable safetensors file ({error})") from None


def read_tensors(path: str | os.PathLike, what: str = "checkpoint",
                 check_digest: bool = True) -> tuple[dict[str, torch.Tensor], dict[str, str]]:
    """The tensors and header metadata of a safetensors file; with ``check_digest`` the
    tensors must match the header's digest."""
    from safetensors.torch import load_file

    path = Path(path)
    header = read_header(path, what)
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError, ValueError) as error:
        raise CheckpointError(f"{path}: not a readable safetensors file ({error})") from None
    if check_digest and header.get(DIGEST_KEY) != tensor_digest(tensors):
        raise CheckpointError(f"{path}: the tensors do not match the {what}'s digest (the file was changed or damaged)")
    for name, tensor in tensors.items():  # NaN weights cannot sample, nor NaN statistics classify
        if tensor.is_floating_point() and not tensor.isfinite().all():
            bad = int((~tensor.isfinite()).sum())
            raise CheckpointError(f"{path}: tensor {name} holds {bad} NaN or infinite value(s)")
    return tensors, header


def stored_layout(path: str | os.PathLike, what: str = "checkpoint") -> dict[str, tuple[tuple[int, ...], str]]:
    """{tensor name: (shape, safetensors dtype name such as "F32")} from the file's header,
    without reading any tensor or loading torch."""
    path = Path(path)
    read_header(path, what)  # a missing or unreadable file, named as such
    try:
        with safe_open(str(path), framework="numpy") as f:
            slices = {name: f.get_slice(name) for name in f.keys()}
            return {name: (tuple(s.get_shape()), s.get_dtype()) for name, s in slices.items()}
    except (SafetensorError, OSError, ValueError) as error:
        raise CheckpointError(f"{path}: not a readable safetensors file ({error})") from None


def content_digest(header: Mapping[str, str]) -> str:
    """SHA-256 of a file's header: its description and, under ``digest``, its tensors' digest."""
    return hashlib.sha256(json.dumps(dict(header), sort_keys=True).encode()).hexdigest()


def keep(source: str | os.PathLike, folder: str | os.PathLike, what: str = "checkpoint") -> tuple[Path, str]:
    """Store a copy of ``source`` in ``folder`` as ``<content digest>.safetensors``, written
    atomically (a file of that digest is already the same file); its path and digest.

    The file is read as ``read_tensors`` reads it, so only a file whose tensors match its
    digest and are finite is kept (CheckpointError naming ``source`` otherwise).
    """
    _, header = read_tensors(source, what)
    digest = content_digest(header)
    target = Path(folder) / f"{digest}{SUFFIX}"
    if not target.is_file():
        with atomic_output(target) as tmp:
            shutil.copyfile(source, tmp)
    return target, digest

