"""MoGlow's two baselines: the causal LSTM regressor and the non-causal conditional VAE."""

from __future__ import annotations

import pytest
import torch
from torch.distributions import Normal, kl_divergence

from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions
from generation.registry import preset
from generation.models.rnn import RNNBaseline, RNNConfig
from generation.models.vae import VAEBaseline, VAEConfig, kl_to_standard_normal

POSE_DIM, CONTROL_DIM, FRAMES = 63, 3, 80
LOCOMOTION = ("walk", "run", "dash", "walk-back", "walk-left", "walk-right")


def lstm_parameters(inputs: int, hidden: int, layers: int = 1, directions: int = 1) -> int:
    """PyTorch's LSTM: per layer and direction, four gates with input and recurrent
    weights and two biases; layers above the first read every direction's output."""
    total = 0
    for layer in range(layers):
        width = inputs if layer == 0 else hidden * directions
        total += directions * 4 * (width * hidden + hidden * hidden + 2 * hidden)
    return total


def linear_parameters(inputs: int, outputs: int) -> int:
    return inputs * outputs + outputs


def small_models() -> list:
    torch.manual_seed(0)
    return [RNNBaseline(RNNConfig(hidden_size=32), POSE_DIM, CONTROL_DIM),
            VAEBaseline(VAEConfig(hidden_size=16), POSE_DIM, CONTROL_DIM)]


def random_control(batch: int = 2) -> torch.Tensor:
    return torch.randn(batch, FRAMES, CONTROL_DIM, generator=torch.Generator().manual_seed(1))


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """These networks are tiny, so one thread is as fast as two; and two OpenMP threads on
    two cores that other jobs keep busy wait on each other, making the module ten times slower."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def locomotion_windows(motion_data, tmp_path_factory) -> dict[str, torch.Tensor]:
    """Standardised training windows of MoGlow's locomotion subset of the real data."""
    options = DatasetOptions(contents=LOCOMOTION)
    dataset = build_dataset(motion_data, options, cache_dir=tmp_path_factory.mktemp("cache"), progress=False)
    return {key: torch.as_tensor(value, dtype=torch.float32) for key, value in dataset.windows("train").items()}


def test_paper_presets_have_the_published_architecture_parameter_counts():
    rnn = RNNBaseline(preset("rnn", "paper"), POSE_DIM, CONTROL_DIM)
    expected_rnn = lstm_parameters(CONTROL_DIM, 512) + linear_parameters(512, POSE_DIM)
    assert sum(p.numel() for p in rnn.parameters()) == expected_rnn

    vae = VAEBaseline(preset("vae", "paper"), POSE_DIM, CONTROL_DIM)
    latent = 2
    expected_vae = (
        lstm_parameters(POSE_DIM + CONTROL_DIM, 256, layers=2, directions=2)  # encoder
        + linear_parameters(2 * 256, 2 * latent)  # mean and log-variance of z
        + lstm_parameters(CONTROL_DIM + latent, 256, layers=2, directions=2)  # decoder
        + linear_parameters(2 * 256, POSE_DIM)
    )
    assert sum(p.numel() for p in vae.parameters()) == expected_vae


def test_unknown_preset_names_are_refused():
    with pytest.raises(ValueError, match="unknown RNN preset"):
        preset("rnn", "huge")
    with pytest.raises(ValueError, match="unknown VAE preset"):
        preset("vae", "huge")


@pytest.mark.parametrize("model", small_models(), ids=lambda m: m.kind)
def test_generate_returns_one_pose_per_control_frame_and_ignores_temperature_and_seed(model):
    control = random_control(batch=3)
    first = model.generate(control, None)
    assert first.shape == (3, FRAMES, POSE_DIM)
    assert model.context_frames == 0
    again = model.generate(control, None, temperature=0.0, generator=torch.Generator().manual_seed(7))
    torch.testing.assert_close(again, first, rtol=0, atol=0)
    pose = torch.randn(3, FRAMES, POSE_DIM)
    loss, metrics = model.loss(pose, control)
    assert loss.shape == () and torch.isfinite(loss) and "mse" in metrics


def test_rnn_is_causal():
    rnn = small_models()[0]
    control = random_control()
    changed = control.clone()
    changed[:, 50:] += 1.0
    before, after = rnn.generate(control, None), rnn.generate(changed, None)
    torch.testing.assert_close(after[:, :50], before[:, :50], rtol=0, atol=1e-6)
    assert (after[:, 50:] - before[:, 50:]).abs().max() > 1e-3


def test_vae_is_not_causal_late_control_changes_earlier_frames():
    vae = small_models()[1]
    control = random_control()
    changed = control.clone()
    changed[:, 50:] += 1.0
    before, after = vae.generate(control, None), vae.generate(changed, None)
    assert (after[:, :50] - before[:, :50]).abs().max() > 1e-3


def test_vae_kl_term_is_the_closed_form_kl_of_the_posterior_to_the_standard_normal():
    mean, log_var = torch.randn(5, 2), torch.randn(5, 2)
    reference = kl_divergence(Normal(mean, (0.5 * log_var).exp()), Normal(0.0, 1.0)).sum(dim=-1)
    torch.testing.assert_close(kl_to_standard_normal(mean, log_var), reference)

    # The KL the loss reports is this, for the encoder's posterior, averaged over the batch.
    vae = small_models()[1]
    pose, control = torch.randn(4, FRAMES, POSE_DIM), random_control(batch=4)
    mean, log_var = vae.encode(pose, control)
    reference = kl_divergence(Normal(mean, (0.5 * log_var).exp()), Normal(0.0, 1.0)).sum(dim=-1).mean()
    _, metrics = vae.loss(pose, control)
    assert metrics["kl"] == pytest.approx(reference.item(), rel=1e-5)


def test_vae_kl_weight_rises_linearly_over_the_annealing_steps_of_training_only():
    vae = VAEBaseline(VAEConfig(hidden_size=8, kl_weight=0.5, kl_anneal_steps=4), POSE_DIM, CONTROL_DIM)
    pose, control = torch.randn(2, FRAMES, POSE_DIM), random_control()
    weights = [vae.loss(pose, control)[1]["kl_weight"] for _ in range(6)]
    assert weights == [0.0, 0.125, 0.25, 0.375, 0.5, 0.5]
    vae.eval()
    with torch.no_grad():
        vae.loss(pose, control)
    assert vae.training_steps.item() == 6  # evaluation does not advance the schedule


@pytest.mark.parametrize("model", small_models(), ids=lambda m: m.kind)
def test_loss_falls_over_the_first_hundred_adam_steps_on_real_locomotion(model, locomotion_windows):
    pose, control = locomotion_windows["pose"], locomotion_windows["control"]
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    batches = torch.Generator().manual_seed(0)
    torch.manual_seed(0)
    losses = []
    for _ in range(100):
        index = torch.randint(len(pose), (32,), generator=batches)
        loss, _ = model.loss(pose[index], control[index])
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    first, last = sum(losses[:10]) / 10, sum(losses[-10:]) / 10
    assert last < 0.9 * first, (first, last)
