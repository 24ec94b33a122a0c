"""Sampling precisions: what ``auto`` picks on which machine, that each precision's matrix
product computes x Wᵀ + b to its rounding, and that int8 stays on the CPU."""

from __future__ import annotations

import pytest
import torch

from generation.models.parts import precision as precision_module
from generation.models.moglow import MoGlow, MoGlowConfig
from generation.models.parts.precision import PRECISIONS, auto_precision, available_precisions, input_dtype, matrix_product


@pytest.mark.parametrize(("bfloat16_units", "expected"), [(True, "bfloat16"), (False, "float32")])
def test_auto_is_bfloat16_on_cpus_with_bfloat16_units_else_float32_never_int8(monkeypatch, bfloat16_units, expected):
    monkeypatch.setattr(precision_module, "cpu_has_bfloat16_units", lambda: bfloat16_units)
    monkeypatch.setattr(precision_module, "cpu_has_int8_products", lambda: True)
    assert auto_precision("cpu", PRECISIONS) == expected


def test_auto_is_float32_for_models_that_offer_nothing_else_and_off_the_cpu():
    assert auto_precision("cpu", ("float32",)) == "float32"
    assert auto_precision("meta", PRECISIONS) == "float32"
    assert "int8" not in available_precisions("meta")


@pytest.mark.parametrize(("precision", "tolerance"), [("float32", 1e-5), ("bfloat16", 0.02), ("int8", 0.03)])
def test_each_precision_multiplies_to_within_its_rounding(precision, tolerance):
    """Relative to the largest output: bfloat16 keeps 8 significant bits, int8 about 8 bits
    of the input and of each weight row."""
    generator = torch.Generator().manual_seed(0)
    weight, bias = torch.randn(64, 300, generator=generator) / 17, torch.randn(64, generator=generator)
    x = torch.randn(8, 300, generator=generator)
    exact = torch.nn.functional.linear(x, weight, bias)
    product = matrix_product(weight, bias, precision)(x.to(input_dtype(precision, weight.dtype))).float()
    error = (product - exact).abs().max() / exact.abs().max()
    assert error < tolerance
    assert precision == "float32" or error > 1e-5  # the lower precision did run


def test_int8_sampling_is_refused_off_the_cpu():
    model = MoGlow(MoGlowConfig(steps=1, tau=2, lstm_hidden=8), pose_dim=4, control_dim=3).to("meta")
    with pytest.raises(ValueError, match="int8 is not available on meta"):
        model.generate(torch.zeros(1, 5, 3, device="meta"), None, precision="int8")
