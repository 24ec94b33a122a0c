"""The one checkpoint store: a file is kept under its content digest, atomically, only if
its tensors match its digest; the same tensors described otherwise are another file."""

from __future__ import annotations

import pytest
import torch

from generation.checkpoints.store import (
    CheckpointError,
    keep,
    read_header,
    write_tensors,
)


def test_a_file_is_kept_once_under_its_content_digest_and_a_damaged_one_not_at_all(tmp_path):
    tensors = {"weight": torch.arange(6.0).reshape(2, 3)}
    first = write_tensors(tmp_path / "a.safetensors", tensors, {"description": "one"})
    other = write_tensors(tmp_path / "b.safetensors", tensors, {"description": "another"})
    store = tmp_path / "store"
    kept, digest = keep(first, store)
    assert kept == store / f"{digest}.safetensors" and kept.read_bytes() == first.read_bytes()
    assert keep(first, store) == (kept, digest)  # the same file once
    assert keep(other, store)[1] != digest  # the same tensors, described otherwise
    assert read_header(first)["digest"] == read_header(other)["digest"]
    damaged = tmp_path / "c.safetensors"
    data = bytearray(first.read_bytes())
    data[-1] ^= 0xFF
    damaged.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="do not match"):
        keep(damaged, store)
    assert sorted(p.name for p in store.iterdir()) == sorted([kept.name, f"{keep(other, store)[1]}.safetensors"])
