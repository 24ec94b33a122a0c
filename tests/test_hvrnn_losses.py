"""HVRNN's loss terms: rotation distances agree with scipy's Rotation, Gram–Schmidt gives
proper rotations, α_k counts bones to the end effectors, and the KL is that of torch."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from generation.models.parts.losses import (
    hierarchical_distance, joint_weights, kl_diagonal_gaussians, matrix_validity, quaternion_distance, quaternion_validity,
    rotation_matrix_distance,
)
from generation.models.parts.rotations import expmap_to_quat, gram_schmidt, matrix_to_quat, normalize_quaternion, quat_to_matrix


def random_rotations(n: int, seed: int) -> Rotation:
    return Rotation.random(n, random_state=seed)


def wxyz(rotations: Rotation) -> torch.Tensor:
    xyzw = rotations.as_quat()
    return torch.as_tensor(np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1))


def test_quaternion_distances_match_scipy_relative_rotation_angles():
    r1, r2 = random_rotations(200, 0), random_rotations(200, 1)
    angle = (r1.inv() * r2).magnitude()  # in [0, π]
    q1, q2 = wxyz(r1), wxyz(r2)
    # Flip half the signs: the same rotations, so the distances must not change.
    q2 = q2 * torch.where(torch.arange(200) % 2 == 0, 1.0, -1.0)[:, None].double()
    np.testing.assert_allclose(quaternion_distance(q1, q2, "d3").numpy(), angle / 2, atol=1e-6)
    np.testing.assert_allclose(quaternion_distance(q1, q2, "d2").numpy(), 1 - np.cos(angle / 2), atol=1e-12)
    np.testing.assert_allclose(quaternion_distance(q1, q2, "d1").numpy(), 2 * np.sin(angle / 4), atol=1e-12)


def test_quaternion_distance_is_zero_for_the_same_rotation_of_either_sign():
    q = wxyz(random_rotations(10, 2))
    for kind in ("d1", "d2", "d3"):
        assert quaternion_distance(q, -q, kind).abs().max() < 1e-3
    with pytest.raises(ValueError, match="unknown quaternion distance 'd4'"):
        quaternion_distance(q, q, "d4")


def test_matrix_distance_is_scipys_relative_rotation_angle():
    r1, r2 = random_rotations(200, 3), random_rotations(200, 4)
    m1, m2 = torch.as_tensor(r1.as_matrix()), torch.as_tensor(r2.as_matrix())
    np.testing.assert_allclose(rotation_matrix_distance(m1, m2).numpy(), (r1.inv() * r2).magnitude(), atol=1e-6)


def test_d3_gradient_is_finite_at_zero_distance():
    q = wxyz(random_rotations(4, 5)).requires_grad_()
    quaternion_distance(q, q.detach(), "d3").sum().backward()
    assert torch.isfinite(q.grad).all()


def test_quaternion_matrix_conversions_match_scipy_both_ways():
    r = random_rotations(500, 6)
    q = wxyz(r)
    np.testing.assert_allclose(quat_to_matrix(q).numpy(), r.as_matrix(), atol=1e-12)
    back = matrix_to_quat(torch.as_tensor(r.as_matrix()))
    assert quaternion_distance(back, q, "d2").max() < 1e-12  # equal up to sign
    # Near-180° rotations, where the w-based formula alone breaks down.
    flips = Rotation.from_rotvec(np.pi * np.eye(3) * 0.999999)
    assert quaternion_distance(matrix_to_quat(torch.as_tensor(flips.as_matrix())), wxyz(flips), "d2").max() < 1e-12


def test_axis_angle_to_quaternion_matches_scipy_and_has_a_finite_gradient_at_zero():
    rotations = random_rotations(200, 3)
    vectors = torch.as_tensor(rotations.as_rotvec())
    vectors[:3] *= torch.tensor([0.0, 1e-5, 1e-3])[:, None]  # zero and tiny rotations too
    expected = wxyz(Rotation.from_rotvec(vectors.numpy()))
    got = expmap_to_quat(vectors)
    # Same rotation, either sign.
    np.testing.assert_allclose(quaternion_distance(got, expected, "d2").numpy(), 0, atol=1e-12)
    np.testing.assert_allclose(got.norm(dim=-1).numpy(), 1, atol=1e-12)
    zero = torch.zeros(1, 3, dtype=torch.float64, requires_grad=True)
    expmap_to_quat(zero).sum().backward()
    assert torch.isfinite(zero.grad).all()


def test_gram_schmidt_gives_orthonormal_matrices_with_determinant_one():
    x = torch.randn(1000, 6, generator=torch.Generator().manual_seed(0), dtype=torch.float64) * 3
    r = gram_schmidt(x)
    eye = torch.eye(3, dtype=torch.float64).expand(1000, 3, 3)
    assert torch.allclose(r.transpose(-1, -2) @ r, eye, atol=1e-12)
    assert torch.allclose(torch.linalg.det(r), torch.ones(1000, dtype=torch.float64), atol=1e-12)
    # The first column keeps its direction; a valid rotation's two columns are returned unchanged.
    assert torch.allclose(r[..., 0], x[:, :3] / x[:, :3].norm(dim=-1, keepdim=True))
    m = torch.as_tensor(random_rotations(5, 7).as_matrix())
    assert torch.allclose(gram_schmidt(torch.cat([m[..., 0], m[..., 1]], -1)), m, atol=1e-12)


def test_validity_penalties_vanish_exactly_on_valid_rotations():
    m = torch.as_tensor(random_rotations(5, 8).as_matrix())
    assert matrix_validity(torch.cat([m[..., 0], m[..., 1]], -1)).abs().max() < 1e-12
    assert torch.allclose(matrix_validity(torch.tensor([[2.0, 0, 0, 1, 1, 0]])), torch.tensor([1 + (2**0.5 - 1) ** 2 + 4.0]))
    q = torch.tensor([[0.0, 0.0, 0.0, 2.0], [0.5, 0.5, 0.5, 0.5]])
    assert torch.allclose(quaternion_validity(q), torch.tensor([1.0, 0.0]))
    assert torch.allclose(normalize_quaternion(q)[0], torch.tensor([0.0, 0.0, 0.0, 1.0]))


def test_joint_weights_count_bones_to_the_farthest_end_effector():
    #        0 (root)
    #       / \
    #      1   4
    #      |   |
    #      2   5
    #      |
    #      3
    parents = [-1, 0, 1, 2, 0, 4]
    assert joint_weights(parents).tolist() == [4.0, 3.0, 2.0, 1.0, 2.0, 1.0]


def test_hierarchical_distance_weighs_each_joint_by_alpha():
    q = wxyz(random_rotations(6, 9)).reshape(2, 3, 4)
    p = wxyz(random_rotations(6, 10)).reshape(2, 3, 4)
    alpha = torch.tensor([3.0, 2.0, 1.0], dtype=torch.float64)
    expected = (quaternion_distance(q, p, "d1") * alpha).sum(-1)
    assert torch.allclose(hierarchical_distance(q, p, alpha, "d1"), expected)
    m, n = quat_to_matrix(q), quat_to_matrix(p)
    # d3 is half the rotation angle, so the SO(3) distance is twice it.
    assert torch.allclose(hierarchical_distance(m, n, alpha, "so3"), 2 * hierarchical_distance(q, p, alpha, "d3"), atol=1e-6)


def test_kl_of_diagonal_gaussians_matches_torch_distributions():
    g = torch.Generator().manual_seed(1)
    mq, mp, lq, lp = (torch.randn(7, 5, generator=g, dtype=torch.float64) for _ in range(4))
    q = torch.distributions.Normal(mq, (0.5 * lq).exp())
    p = torch.distributions.Normal(mp, (0.5 * lp).exp())
    expected = torch.distributions.kl_divergence(q, p).sum(-1)
    assert torch.allclose(kl_diagonal_gaussians(mq, lq, mp, lp), expected, atol=1e-12)
    assert kl_diagonal_gaussians(mq, lq, mq, lq).abs().max() < 1e-12
