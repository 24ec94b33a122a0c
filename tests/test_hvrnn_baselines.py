"""ERD and QuaterNet baselines: forward kinematics, training on real data, checkpoints, sampling."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from generation.checkpoints.checkpoint import load_checkpoint
from generation.control import AttributeControl
from generation.generator import Generator
from generation.models.parts.kinematics import forward_kinematics
from generation.motion.kinematics import forward_kinematics as numpy_forward_kinematics
from generation.motion.rotations import quat_to_matrix
from generation.registry import model_class
from generation.train import TrainOptions, train
from tests.hvrnn_setup import data  # noqa: F401  (a fixture)

TINY = {"erd": {"encoder": (32,), "hidden": 32, "decoder": (32,), "batch_size": 8},
        "quaternet": {"hidden": 32, "batch_size": 8}}


@pytest.fixture(scope="module")
def checkpoints(data, tmp_path_factory):
    torch.set_num_threads(1)
    folder = tmp_path_factory.mktemp("baselines")
    for kind, overrides in TINY.items():
        train(kind, "cpu", data, folder / f"{kind}.safetensors", TrainOptions(steps=40, eval_every=40),
              progress=False, overrides=overrides)
    return folder


def test_torch_forward_kinematics_matches_numpy(data):
    skeleton = data.dataset.skeleton
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(5, skeleton.n_joints, 4))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    rotations = quat_to_matrix(quats)
    expected = numpy_forward_kinematics(rotations, np.broadcast_to(skeleton.offsets, (5, skeleton.n_joints, 3)),
                                        skeleton.parents)
    got = forward_kinematics(torch.as_tensor(rotations), torch.as_tensor(skeleton.offsets), list(skeleton.parents))
    assert np.allclose(got.numpy(), expected, atol=1e-9)


@pytest.mark.parametrize("kind", sorted(TINY))
def test_training_lowers_the_loss_on_real_data(kind, data, checkpoints):
    trained, meta = load_checkpoint(checkpoints / f"{kind}.safetensors")
    torch.manual_seed(0)
    fresh = model_class(kind)(trained.config, meta.pose_dim, meta.control_dim)
    fresh.prepare(data)
    pose, mask, action, style = data.sequences("train", data.standardizer("root")).subset(np.arange(0, 160, 4)).tensors()
    with torch.no_grad():
        before = fresh.eval().loss(pose, mask, action, style)[1]["reconstruction"]
        after = trained.loss(pose, mask, action, style)[1]["reconstruction"]
    assert after < 0.8 * before, (before, after)


@pytest.mark.parametrize("kind", sorted(TINY))
def test_checkpoint_reloads_and_samples_reproducibly(kind, data, checkpoints):
    path = checkpoints / f"{kind}.safetensors"
    first, second = Generator.load(path), Generator.load(path)
    for name, tensor in first.model.state_dict().items():
        assert torch.equal(tensor, second.model.state_dict()[name]), name
    control = AttributeControl(data.actions.names[0], data.styles.names[0], frames=45, fps=data.fps)
    a = first.sample(control, n=2, seed=5)
    b = second.sample(control, n=2, seed=5)
    c = first.sample(control, n=2, seed=6)
    assert len(a) == 2 and a[0].positions.shape == (45, data.dataset.skeleton.n_joints, 3)
    assert np.isfinite(a[0].positions).all()
    assert all(np.array_equal(x.positions, y.positions) for x, y in zip(a, b))
    # The sampled initial state is the only randomness: another seed, another motion.
    assert not np.allclose(a[0].positions, c[0].positions)
    assert not np.allclose(a[0].positions, a[1].positions)
    with pytest.raises(ValueError, match="unknown action 'swim'"):
        first.sample(AttributeControl("swim", data.styles.names[0], frames=10, fps=data.fps))


def test_quaternet_loss_ignores_quaternion_signs(data, checkpoints):
    model, _ = load_checkpoint(checkpoints / "quaternet.safetensors")
    pose = torch.as_tensor(data.sequences("test", data.standardizer("root")).features[:2, :30])
    flipped = pose.clone()
    flipped[..., 6:] *= -1
    assert torch.allclose(model.frame_error(model.normalise(pose), pose), torch.zeros(2, 30), atol=1e-6)
    assert torch.allclose(model.frame_error(model.normalise(flipped), pose), torch.zeros(2, 30), atol=1e-6)
