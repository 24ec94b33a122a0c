"""The precisions sampling multiplies in, and which one a machine multiplies fastest.

Sampling an autoregressive model spends its time in matrix products with fixed weights
(for MoGlow, its coupling networks' LSTMs and output layers), so those products are what
a lower precision speeds up; everything else stays in the parameters' dtype.

- ``float32``: the parameters' own dtype (float32 for every trained model); exact.
- ``bfloat16``: weights and inputs rounded to 8 significant bits, sums in float32. Fast
  only where the hardware multiplies bfloat16 (CPUs with AVX512-BF16 or AMX, GPUs);
  elsewhere torch emulates it many times slower than float32.
- ``int8``: dynamic quantisation, as ``torch.ao.quantization.quantize_dynamic`` does for
  ``nn.Linear``: weights rounded to int8 once per output channel, the input scaled to
  8 bits as it arrives, sums in int32 (fbgemm on x86 CPUs: AVX2, and AVX512-VNNI where
  present). CPU only. Its input scale is per tensor, so a sample's rounding depends on
  the other samples of the same batch (the same seed and ``n`` still reproduce a run).

``auto`` is bfloat16 on CPUs with bfloat16 units and float32 on anything else: bfloat16
samples of the trained MoGlow stay within the bound ``tests/test_moglow.py`` holds them
to (under 1 cm per joint, and under 1/20 of a change of seed), int8 samples do not (README,
``sample --precision``), so int8 is there to be asked for, never the default.
"""

from __future__ import annotations

import warnings
from typing import Callable

import torch

PRECISIONS = ("float32", "bfloat16", "int8")
MatrixProduct = Callable[[torch.Tensor], torch.Tensor]


def cpu_has_bfloat16_units() -> bool:
    """Whether this CPU multiplies bfloat16 natively (AVX512-BF16 or AMX)."""
    return torch.ops.mkldnn._is_mkldnn_bf16_supported()


def cpu_has_int8_products() -> bool:
    """Whether torch can multiply dynamically quantised int8 here (fbgemm, x86 CPUs)."""
    return "fbgemm" in torch.backends.quantized.supported_engines


def available_precisions(device: torch.device | str = "cpu") -> tuple[str, ...]:
    """The precisions that run on ``device`` (int8 needs fbgemm on the CPU)."""
    on_cpu = torch.device(device).type == "cpu"
    return tuple(p for p in PRECISIONS if p != "int8" or (on_cpu and cpu_has_int8_products()))


def auto_precision(device: torch.device | str, offered: tuple[str, ...]) -> str:
    """The precision ``auto`` means on ``device`` for a model that offers ``offered``."""
    if torch.device(device).type == "cpu" and "bfloat16" in offered and cpu_has_bfloat16_units():
        return "bfloat16"
    return "float32"


def input_dtype(precision: str, parameter_dtype: torch.dtype) -> torch.dtype:
    """The dtype a product of ``precision`` takes its input in (and the hidden state is kept in)."""
    return {"float32": parameter_dtype, "bfloat16": torch.bfloat16, "int8": torch.float32}[precision]


def matrix_product(weight: torch.Tensor, bias: torch.Tensor, precision: str) -> MatrixProduct:
    """x ↦ x @ weightᵀ + bias in ``precision``, prepared once (weights converted here), for
    x in ``input_dtype(precision, weight.dtype)``; the result comes in that dtype too."""
    if precision == "int8":
        return _int8_product(weight, bias)
    dtype = input_dtype(precision, weight.dtype)
    if dtype == torch.bfloat16 and weight.device.type == "cpu" and cpu_has_bfloat16_units():
        return _onednn_bfloat16_product(weight, bias)
    if dtype == weight.dtype:
        weight_t = weight.T  # MKL multiplies the transposed view as fast, and exactly as nn.Linear does
    else:
        weight_t = weight.to(dtype).T.contiguous()  # oneDNN multiplies a contiguous copy faster
    bias = bias.to(dtype)
    return lambda x: torch.addmm(bias, x, weight_t)


def _onednn_bfloat16_product(weight: torch.Tensor, bias: torch.Tensor) -> MatrixProduct:
    # addmm hands oneDNN a plain matrix, which it reorders into its blocked layout on every
    # call: a copy of every weight per frame. Reordered once here (with the ops torch's
    # compiler uses for frozen linear layers), MoGlow paper's coupling products gave the
    # same bits 1.3x (batch 64) to 1.7x (batch 1) faster on this machine.
    packed = torch.ops.mkldnn._reorder_linear_weight(weight.detach().to(torch.bfloat16))
    bias = bias.detach().to(torch.bfloat16)
    return lambda x: torch.ops.mkldnn._linear_pointwise(x, packed, bias, "none", [], "")


def _int8_product(weight: torch.Tensor, bias: torch.Tensor) -> MatrixProduct:
    weight = weight.detach().float()
    scale = (weight.abs().amax(dim=1) / 127).clamp_min(torch.finfo(torch.float32).tiny)
    with warnings.catch_warnings():
        # torch 2.13 deprecates quantised tensors in favour of torchao; until they go,
        # they are how fbgemm's packed int8 weights are made.
        warnings.filterwarnings("ignore", message=".*quantize_per_channel.*deprecated")
        quantised = torch.quantize_per_channel(weight, scale, torch.zeros_like(scale, dtype=torch.long), 0, torch.qint8)
    packed = torch.ops.quantized.linear_prepack(quantised, bias.detach().float())
    # reduce_range: 7-bit inputs where fbgemm would otherwise saturate AVX2's pairwise int16 sums.
    return lambda x: torch.ops.quantized.linear_dynamic(x, packed, True)
