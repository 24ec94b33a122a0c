"""Invertible transforms of sequences, the parts of a Glow step of flow as MoGlow uses it.

Every transform maps ``x`` (batch, frames, dim) to ``(y, logabsdet)`` where ``logabsdet``
(batch, frames) is log|det ∂y_t/∂x_t| of each frame, and ``inverse`` maps back, returning
the log-determinant of the inverse. ``context`` (batch, frames, context_dim) is the
conditioning information; only the coupling uses it.

Sampling inverts the flow one frame at a time. ``frame_inverse(precision)`` returns
a callable ``(y_t, context_t) -> x_t`` for that, with everything that does not change
between frames (inverse weight matrices, concatenated LSTM weights) computed once, and
with the recurrent state of the coupling network kept inside the callable rather than
the module. ``precision`` (one of ``precision.PRECISIONS``; "float32" is the parameters'
own dtype) is that of the coupling networks' matrix products, where sampling spends its
time. Everything else (actnorm, the inverse linear map, the affine arithmetic of the
coupling, the LSTM cell state) stays in the parameters' dtype. Call it under
``torch.inference_mode()``, as ``MoGlow.generate`` does.
"""

from __future__ import annotations

import weakref
from typing import Callable

import torch
from torch import nn

from .precision import MatrixProduct, input_dtype, matrix_product

FrameInverse = Callable[[torch.Tensor, torch.Tensor | None], torch.Tensor]
# AffineCoupling._sampling_products' prepared weights, outside the modules so that copying
# or saving a module never meets them (oneDNN's reordered tensors cannot be copied).
_PREPARED_PRODUCTS: weakref.WeakKeyDictionary[nn.Module, dict[str, tuple[list, list[MatrixProduct]]]] = (
    weakref.WeakKeyDictionary())


class ActNorm(nn.Module):
    """y = (x + bias) * exp(log_scale), per dimension (Glow, Sec. 3.1).

    The first batch seen in training sets bias and scale so that its output has zero
    mean and unit variance in every dimension; the ``initialized`` buffer records that
    this happened, so a loaded checkpoint is not re-initialised.
    """

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.bias = nn.Parameter(torch.zeros(dim))
        self.log_scale = nn.Parameter(torch.zeros(dim))
        self.register_buffer("initialized", torch.tensor(False))

    @torch.no_grad()
    def _initialize(self, x: torch.Tensor) -> None:
        flat = x.reshape(-1, x.shape[-1])
        self.bias.copy_(-flat.mean(0))
        self.log_scale.copy_(-torch.log(flat.std(0, unbiased=False) + 1e-6))
        self.initialized.fill_(True)

    def forward(self, x: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        if self.training and not self.initialized:
            self._initialize(x)
        y = (x + self.bias) * torch.exp(self.log_scale)
        return y, self.log_scale.sum().expand(x.shape[:-1])

    def inverse(self, y: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        x = y * torch.exp(-self.log_scale) - self.bias
        return x, (-self.log_scale.sum()).expand(y.shape[:-1])

    def frame_inverse(self, precision: str = "float32") -> FrameInverse:
        inverse_scale, negative_bias = torch.exp(-self.log_scale), -self.bias
        return lambda y, context: torch.addcmul(negative_bias, y, inverse_scale)


class InvertibleLinearLU(nn.Module):
    """y = W x with W = P L (U + diag(s)), s = sign * exp(log_s) (Glow's LU-decomposed 1×1 convolution).

    P (a permutation) and the signs of s are fixed; L is unit lower triangular and U
    strictly upper triangular. log|det W| = Σ log|s|, so the determinant costs nothing.
    W starts as a random rotation, which mixes all dimensions from the first step.
    """

    def __init__(self, dim: int) -> None:
        super().__init__()
        rotation, _ = torch.linalg.qr(torch.randn(dim, dim, dtype=torch.float64))
        permutation, lower, upper = torch.linalg.lu(rotation)
        s = torch.diagonal(upper)
        self.register_buffer("permutation", permutation.float())
        self.register_buffer("sign_s", torch.sign(s).float())
        self.lower = nn.Parameter(torch.tril(lower, -1).float())
        self.upper = nn.Parameter(torch.triu(upper, 1).float())
        self.log_s = nn.Parameter(torch.log(torch.abs(s)).float())
        # Masks keep L and U triangular whatever the optimiser does to the zero entries.
        self.register_buffer("lower_mask", torch.tril(torch.ones(dim, dim), -1), persistent=False)
        self.register_buffer("eye", torch.eye(dim), persistent=False)

    def _factors(self) -> tuple[torch.Tensor, torch.Tensor]:
        lower = self.lower * self.lower_mask + self.eye
        upper = self.upper * self.lower_mask.T + torch.diag(self.sign_s * torch.exp(self.log_s))
        return lower, upper

    def weight(self) -> torch.Tensor:
        lower, upper = self._factors()
        return self.permutation @ lower @ upper

    def inverse_weight(self) -> torch.Tensor:
        """W⁻¹ = (U + diag(s))⁻¹ L⁻¹ Pᵀ by triangular solves (exact and cheap)."""
        lower, upper = self._factors()
        lower_inv_pt = torch.linalg.solve_triangular(lower, self.permutation.T, upper=False, unitriangular=True)
        return torch.linalg.solve_triangular(upper, lower_inv_pt, upper=True)

    def forward(self, x: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        return x @ self.weight().T, self.log_s.sum().expand(x.shape[:-1])

    def inverse(self, y: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        return y @ self.inverse_weight().T, (-self.log_s.sum()).expand(y.shape[:-1])

    def frame_inverse(self, precision: str = "float32") -> FrameInverse:
        inverse_t = self.inverse_weight().T.contiguous()
        return lambda y, context: y @ inverse_t


def coupling_scale(h: torch.Tensor, offset: float = 0.0, floor: float = 0.05) -> torch.Tensor:
    """The coupling's scale, sigmoid(h + offset) + floor (see ``AffineCoupling``); the reference
    implementation's is sigmoid(h) + 0.05, the authors' public code's sigmoid(h + 2) + 1e-6."""
    return torch.sigmoid(h + offset) + floor


class AffineCoupling(nn.Module):
    """x = (x_a, x_b) ↦ (y_a, x_b) with y_a = (x_a + t) ⊙ scale, scale = sigmoid(h + offset) + floor.

    (h, t) = A(x_b, context) where A is a unidirectional LSTM followed by a linear layer,
    run along the frames, so each frame's transform depends on x_b and the context of
    all earlier frames too. The shift is added before scaling. The last layer starts at zero, so every coupling starts as the same
    fixed scaling. The floor (0.05 by default) on the scale bounds how far one coupling
    can shrink a dimension (the inverse divides by the scale), which keeps sampling
    stable. The authors' code uses offset 2 and floor 1e-6 (``generation.stylegestures``).

    x_b is the first ``dim // 2`` dimensions and x_a the rest.
    """

    def __init__(self, dim: int, context_dim: int, hidden: int, layers: int,
                 scale_offset: float = 0.0, scale_floor: float = 0.05) -> None:
        super().__init__()
        self.split = dim // 2
        self.scale_offset, self.scale_floor = scale_offset, scale_floor
        self.lstm = nn.LSTM(self.split + context_dim, hidden, num_layers=layers, batch_first=True)
        self.out = nn.Linear(hidden, 2 * (dim - self.split))
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def _scale_and_shift(self, x_b: torch.Tensor, context: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        hidden, _ = self.lstm(torch.cat([x_b, context], dim=-1))
        h, shift = self.out(hidden).chunk(2, dim=-1)
        return coupling_scale(h, self.scale_offset, self.scale_floor), shift

    def forward(self, x: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        x_b, x_a = x[..., : self.split], x[..., self.split :]
        scale, shift = self._scale_and_shift(x_b, context)
        return torch.cat([x_b, (x_a + shift) * scale], dim=-1), torch.log(scale).sum(-1)

    def inverse(self, y: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        x_b, y_a = y[..., : self.split], y[..., self.split :]
        scale, shift = self._scale_and_shift(x_b, context)
        return torch.cat([x_b, y_a / scale - shift], dim=-1), -torch.log(scale).sum(-1)

    def frame_products(self) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """(weight, bias) of each matrix product the network makes per frame when sampling,
        as ``nn.Linear`` holds them: per LSTM layer, (input, h) times [W_ih W_hh]; then the
        output layer."""
        lstm = self.lstm
        return [
            (torch.cat([getattr(lstm, f"weight_ih_l{k}"), getattr(lstm, f"weight_hh_l{k}")], dim=1),
             getattr(lstm, f"bias_ih_l{k}") + getattr(lstm, f"bias_hh_l{k}"))
            for k in range(lstm.num_layers)
        ] + [(self.out.weight, self.out.bias)]

    def frame_inverse(self, precision: str = "float32") -> FrameInverse:
        return _CouplingFrameInverse(self, self._sampling_products(precision), precision)

    def _sampling_products(self, precision: str) -> list[MatrixProduct]:
        """``frame_products()`` prepared for ``precision``, kept while the parameters stay
        the same tensors, unchanged: casting and reordering the weights costs as much as
        several frames at batch 1, and a study's worker samples one model many times. The
        price is a prepared copy of the weights beside the parameters for each precision
        used (half their size in bfloat16)."""
        prepare = lambda: [matrix_product(w, b, precision) for w, b in self.frame_products()]  # noqa: E731
        if any(p.is_inference() for p in self.parameters()):  # no version counter tells of a change
            return prepare()
        key = [(p.data_ptr(), p._version) for p in self.parameters()]
        prepared = _PREPARED_PRODUCTS.setdefault(self, {})
        if precision not in prepared or prepared[precision][0] != key:
            prepared[precision] = (key, prepare())
        return prepared[precision][1]


class _CouplingFrameInverse:
    """One frame of ``AffineCoupling.inverse``, carrying the LSTM state between calls:
    sampling's fast path, ``nn.LSTM``'s arithmetic arranged for speed.

    Each LSTM layer is one matrix product of (input, h) with [W_ih W_hh], prepared once
    (``AffineCoupling._sampling_products``): fewer and larger products, and fewer
    elementwise calls, than ``torch.lstm_cell`` or ``nn.LSTM`` make, which is where sampling
    spends its time. The products run in ``precision`` (their inputs and the hidden state
    are kept in its input dtype); gates, cell state, scale and shift are computed in the
    parameters' dtype. Around the products, at batch 64, fresh tensors, casts and
    concatenations cost a quarter of the time, so each layer's input is a buffer written
    in place, (x_b, context, h_0) and (h_0, h_1), the new hidden state goes straight into
    it, and the gates and cell state live in buffers too: a frame allocates no large
    tensor and concatenates nothing large.
    """

    def __init__(self, coupling: AffineCoupling, products: list[MatrixProduct], precision: str) -> None:
        *self.layers, self.out = products
        self.dtype = input_dtype(precision, coupling.out.weight.dtype)
        self.split, self.scale_terms = coupling.split, (coupling.scale_offset, coupling.scale_floor)
        self.hidden_size = coupling.lstm.hidden_size
        self.inputs: list[torch.Tensor] = []  # allocated at the first frame, when the batch is known

    def _allocate(self, y: torch.Tensor, context: torch.Tensor | None) -> None:
        batch, size = y.shape[0], self.hidden_size
        first = self.split + (0 if context is None else context.shape[1]) + size
        self.inputs = [y.new_zeros(batch, first, dtype=self.dtype)]
        self.inputs += [y.new_zeros(batch, 2 * size, dtype=self.dtype) for _ in self.layers[1:]]
        self.cells = [y.new_zeros(batch, size) for _ in self.layers]
        self.gates, self.sigmoids = y.new_empty(batch, 4 * size), y.new_empty(batch, 4 * size)
        self.tanhs = y.new_empty(batch, size)

    def __call__(self, y: torch.Tensor, context: torch.Tensor | None) -> torch.Tensor:
        x_b, y_a = y[:, : self.split], y[:, self.split :]
        if not self.inputs:
            self._allocate(y, context)
        size, inputs = self.hidden_size, self.inputs
        inputs[0][:, : self.split] = x_b
        if context is not None:  # in the products' input dtype already (cast once per frame by Flow)
            inputs[0][:, self.split : -size] = context
        for k, product in enumerate(self.layers):
            gates = product(inputs[k])
            if gates.dtype != y.dtype:
                gates = self.gates.copy_(gates)
            # nn.LSTM's gate order is (input, forget, cell, output); one sigmoid serves three.
            sigmoids = torch.sigmoid(gates, out=self.sigmoids)
            cell_input = torch.tanh(gates[:, 2 * size : 3 * size], out=self.tanhs)
            cell = self.cells[k].mul_(sigmoids[:, size : 2 * size]).addcmul_(sigmoids[:, :size], cell_input)
            hidden = inputs[k][:, -size:]  # where layer k reads it at the next frame
            torch.mul(sigmoids[:, 3 * size :], torch.tanh(cell, out=self.tanhs), out=hidden)
            if k + 1 < len(inputs):
                inputs[k + 1][:, :size] = hidden
        h, shift = self.out(inputs[-1][:, -size:]).to(y.dtype).chunk(2, dim=1)
        return torch.cat([x_b, y_a / coupling_scale(h, *self.scale_terms) - shift], dim=1)


class Flow(nn.Module):
    """A composition of transforms: forward applies them in order and sums the log-determinants."""

    def __init__(self, transforms: list[nn.Module]) -> None:
        super().__init__()
        self.transforms = nn.ModuleList(transforms)

    def forward(self, x: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        total = x.new_zeros(x.shape[:-1])
        for transform in self.transforms:
            x, logabsdet = transform(x, context)
            total = total + logabsdet
        return x, total

    def inverse(self, y: torch.Tensor, context: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        total = y.new_zeros(y.shape[:-1])
        for transform in reversed(self.transforms):
            y, logabsdet = transform.inverse(y, context)
            total = total + logabsdet
        return y, total

    def frame_inverse(self, precision: str = "float32") -> FrameInverse:
        steps = [transform.frame_inverse(precision) for transform in reversed(self.transforms)]
        dtype = next(self.parameters()).dtype
        network_dtype = input_dtype(precision, dtype)

        def invert(y: torch.Tensor, context: torch.Tensor | None) -> torch.Tensor:
            if network_dtype != dtype and context is not None:
                context = context.to(network_dtype)  # once for all couplings
            for step in steps:
                y = step(y, context)
            return y

        return invert


def glow_step(dim: int, context_dim: int, hidden: int, layers: int,
              scale_offset: float = 0.0, scale_floor: float = 0.05) -> list[nn.Module]:
    """One step of flow: actnorm, then an invertible linear map, then an affine coupling."""
    return [ActNorm(dim), InvertibleLinearLU(dim),
            AffineCoupling(dim, context_dim, hidden, layers, scale_offset, scale_floor)]
