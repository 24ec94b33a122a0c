"""A small training loop for the networks trained on attribute-labelled sequences.

Adam on random minibatches (drawn with a seeded generator, so a run is reproducible),
optional gradient-norm clipping, and the loss of every step returned for inspection.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from tqdm import tqdm


def fit(module: torch.nn.Module, batch_loss: Callable[[np.ndarray], torch.Tensor], n_items: int, steps: int,
        batch_size: int, lr: float = 1e-3, clip_norm: float | None = None, seed: int = 0,
        progress: bool = False, description: str = "training") -> list[float]:
    """Minimise ``batch_loss(indices)`` over ``steps`` minibatches of item indices."""
    if n_items < 1:
        raise ValueError("nothing to train on: no items")
    if steps < 1 or batch_size < 1:
        raise ValueError(f"steps and batch size must be at least 1, got {steps} and {batch_size}")
    torch.manual_seed(seed)  # dropout, noise and any sampling inside the loss
    rng = np.random.default_rng(seed)
    optimizer = torch.optim.Adam(module.parameters(), lr=lr)
    module.train()
    losses = []
    for _ in tqdm(range(steps), desc=description, unit="step", disable=not progress):
        loss = batch_loss(rng.integers(0, n_items, size=batch_size))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if clip_norm is not None:
            torch.nn.utils.clip_grad_norm_(module.parameters(), clip_norm)
        optimizer.step()
        losses.append(float(loss.detach()))
    module.eval()
    return losses
