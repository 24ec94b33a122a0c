"""HVRNN: a hierarchical variational RNN over motion words, controlled by action and style.

Ghorbani, Wloka, Etemad, Brubaker and Troje, "Probabilistic Character Motion Synthesis
using a Hierarchical Deep Latent Variable Model", Computer Graphics Forum 39(8), 2020.

Level one, motion words: a window of l poses x_t = (x_{lt}, ..., x_{lt+l-1}) is encoded
to w_t = f_enc^w(x_t) and decoded by f_dec^w. Level two, the Motion Cell, a VRNN over
words with control features a = f_c(c) of the one-hot action and style c:

    prior       p(z_t | h_{t-1}, a)        = N(μ, σ²) from an MLP of (h_{t-1}, a)
    posterior   q(z_t | w_t, h_{t-1}, a)   = N(μ, σ²) from an MLP of (f_w(w_t), h_{t-1}, a)
    decoder     ŵ_t = f_dec(f_z(z_t), h_{t-1}, a),   x̂_t = normalise(f_dec^w(ŵ_t))
    transition  h_t = f_h(f_w(w_t), f_z(z_t), a; h_{t-1})   (two stacked GRU cells)

h_0 is drawn from a learned Gaussian of the (action, style) pair
(``initial_state.LabelledInitialState``). Output normalisation
makes every joint rotation valid: quaternions are scaled to unit length, 6-D outputs
become matrices by Gram–Schmidt, or rotation vectors (axis-angle, valid as they are)
become quaternions. Root values (velocities, height, pitch, roll) are
standardised, quaternions are not (``standardization = "root"``).

The loss (Sec. 3.5) per frame is the hierarchical geodesic distance Σ_k α_k d(q̂_k, q_k)
(times ``reconstruction_weight``) plus the root values' squared error, plus β(step) ×
the KL of posterior from prior per frame, the motion-word autoencoder's own
reconstruction, the rotation-validity penalty, ``initial_kl_weight`` × the initial
state's KL from N(0, I), and λ_CL(step) × the classifier loss
(feature matching on the attribute classifiers' intermediate activations and cross
entropy of their predictions on the labels). β is 0 while warming up, rises linearly
while annealing, and stays 1 while cooling down. With a probability that grows over
training, the transition reads the model's own re-encoded output instead of the real
motion word ("motion-word drop"), so it learns to continue from what it generates.
The model counts its own training steps (a buffer saved with it) for these schedules.
In eval mode the loss is schedule-free: β = 1, no classifier term, no word drop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import torch
from torch import nn
from torch.nn import functional as F

from ..motion.features import ROOT_DIMS
from .attribute import AttributeModel
from .parts.initial_state import LabelledInitialState
from .parts.layers import mlp, random_crop
from .parts.noise import RowGenerators, normal
from .parts.losses import (
    QUATERNION_DISTANCES, hierarchical_distance, joint_weights, kl_diagonal_gaussians, masked_mean, matrix_validity,
    quaternion_distance, quaternion_validity,
)
from .parts.rotations import align_quaternions, expmap_to_quat, gram_schmidt, matrix_to_quat, normalize_quaternion, quat_to_matrix

# Numbers a decoded frame carries per joint for each rotation output.
ROTATION_OUTPUT_SIZES = {"quaternion": 4, "matrix": 6, "axis_angle": 3}



@dataclass
class HVRNNConfig:
    """Hyperparameters; the defaults are the sizes of Table 1 (the ``paper`` preset)."""

    word_length: int = 3  # l, poses per motion word
    word_dim: int = 96  # D_w
    word_hidden: int = 256  # hidden width of f_enc^w and f_dec^w
    latent_dim: int = 96  # z
    feature_dim: int = 256  # outputs of f_w and f_z
    mlp_hidden: int = 256  # hidden width of the prior, posterior and f_dec MLPs
    state_dim: int = 512  # units of each GRU cell of f_h
    state_layers: int = 2
    control_features: int = 8  # a = f_c(c)
    # "quaternion", "matrix" (6-D per joint made a rotation by Gram–Schmidt) or
    # "axis_angle" (a rotation vector per joint, valid as it is)
    rotation_output: str = "quaternion"
    distance: str = "d2"  # quaternion distance d1, d2 or d3 (matrices always use the SO(3) angle)
    word_codec: bool = True  # False (ablation SL): words are the raw poses, no f_enc^w / f_dec^w
    hierarchical: bool = True  # False (ablation NL): every α_k = 1
    reconstruction_weight: float = 100.0  # on Σ_k α_k d_k (α normalised to mean 1)
    root_weight: float = 1.0  # on the squared error of the six standardised root values
    word_weight: float = 1.0  # on the motion-word autoencoder's reconstruction
    validity_weight: float = 1.0  # on the rotation-validity penalty of the raw outputs
    initial_kl_weight: float = 1e-3  # on the initial state's KL from N(0, I), per sequence
    classifier_weight: float = 0.1  # λ_CL (0: ablation NC)
    classifier_start: int = 2000  # steps before the classifier loss starts ...
    classifier_ramp: int = 2000  # ... and over which it rises to λ_CL
    kl_warmup: int = 1000  # steps with β = 0
    kl_anneal: int = 5000  # steps over which β rises to 1; then it stays 1 (cool-down)
    word_drop: float = 0.25  # highest probability of feeding back the model's own word
    word_drop_steps: int = 10000  # steps over which that probability rises from 0
    # Training on a random stretch of this many frames of each sequence (0: whole
    # sequences, as in the paper) makes a step cheaper; generation length is unaffected.
    crop_frames: int = 0
    # The label vocabularies, filled in from the training data.
    actions: tuple[str, ...] = ()
    styles: tuple[str, ...] = ()


class GaussianHead(nn.Module):
    """An MLP giving the mean and log-variance of a diagonal Gaussian."""

    def __init__(self, inputs: int, hidden: int, outputs: int) -> None:
        super().__init__()
        self.net = mlp([inputs, hidden, hidden, 2 * outputs])

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        mean, logvar = self.net(x).chunk(2, dim=-1)
        return mean, logvar


class HVRNN(AttributeModel):
    kind = "hvrnn"
    per_row_seeds = True
    Config = HVRNNConfig

    def __init__(self, config: HVRNNConfig, pose_dim: int, control_dim: int) -> None:
        super().__init__(config, pose_dim, control_dim)
        if config.rotation_output not in ROTATION_OUTPUT_SIZES:
            raise ValueError(f"rotation_output must be one of {tuple(ROTATION_OUTPUT_SIZES)}, not {config.rotation_output!r}")
        if config.distance not in QUATERNION_DISTANCES:
            raise ValueError(f"distance must be one of {QUATERNION_DISTANCES}, not {config.distance!r}")
        if (pose_dim - ROOT_DIMS) % 4 or pose_dim <= ROOT_DIMS:
            raise ValueError(f"HVRNN reads six root values and a quaternion per joint; pose_dim {pose_dim} is not 6 + 4k")
        if config.word_length < 1:
            raise ValueError(f"word_length must be at least 1, not {config.word_length}")
        self.joints = (pose_dim - ROOT_DIMS) // 4
        c, l = config, config.word_length
        per_joint = ROTATION_OUTPUT_SIZES[c.rotation_output]
        self.raw_dim = ROOT_DIMS + self.joints * per_joint  # one decoded frame before normalisation
        word_dim = c.word_dim if c.word_codec else l * pose_dim
        decoded_word = c.word_dim if c.word_codec else l * self.raw_dim
        if c.word_codec:
            self.word_encoder = mlp([l * pose_dim, c.word_hidden, c.word_dim])  # f_enc^w
            self.word_decoder = mlp([c.word_dim, c.word_hidden, l * self.raw_dim])  # f_dec^w
        self.control_net = nn.Linear(control_dim, c.control_features)  # f_c
        self.word_features = mlp([word_dim, c.feature_dim, c.feature_dim])  # f_w
        self.latent_features = mlp([c.latent_dim, c.feature_dim, c.feature_dim])  # f_z
        self.prior = GaussianHead(c.state_dim + c.control_features, c.mlp_hidden, c.latent_dim)
        self.posterior = GaussianHead(c.feature_dim + c.state_dim + c.control_features, c.mlp_hidden, c.latent_dim)
        self.decoder = mlp([c.feature_dim + c.state_dim + c.control_features, c.mlp_hidden, c.mlp_hidden, decoded_word])
        cell_inputs = [2 * c.feature_dim + c.control_features] + [c.state_dim] * (c.state_layers - 1)
        self.cells = nn.ModuleList(nn.GRUCell(n, c.state_dim) for n in cell_inputs)  # f_h
        combinations = len(self.actions) * len(self.styles)
        self.initial = LabelledInitialState(combinations, c.state_layers * c.state_dim, initial_logvar=-2.0)
        # Constants of the training data, set by prepare(): α_k, the root values'
        # standardisation, and a rotation per joint whose hemisphere every input
        # quaternion is flipped into (q and −q are one rotation; the encoder should
        # see one sign).
        self.register_buffer("alpha", torch.ones(self.joints))
        self.register_buffer("root_mean", torch.zeros(ROOT_DIMS))
        self.register_buffer("root_std", torch.ones(ROOT_DIMS))
        self.register_buffer("reference", torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(self.joints, 1))
        self.register_buffer("step", torch.zeros((), dtype=torch.long))  # training steps taken
        self.classifiers: tuple[Any, ...] = ()  # frozen attribute classifiers, not part of the state
        for module in self.modules():
            if isinstance(module, nn.Linear):  # Kaiming initialisation (Sec. 4.2)
                nn.init.kaiming_normal_(module.weight, nonlinearity="relu")
                nn.init.zeros_(module.bias)

    # --- data-derived constants -------------------------------------------------------

    def prepare(self, data: Any) -> None:
        """Constants from the training data (``AttributeData``): α_k from its skeleton
        (normalised to mean 1; all 1 for NL), the root standardisation, the quaternion
        sign reference. The classifiers of the classifier loss come from the trainer
        (``use_classifiers``)."""
        spec = data.dataset.angle_spec
        alpha = torch.as_tensor(joint_weights(data.dataset.skeleton.parents)[list(spec.joints)], dtype=torch.float32)
        if len(alpha) != self.joints:
            raise ValueError(f"the skeleton has {len(alpha)} rotated joints, the model {self.joints}")
        self.alpha.copy_(alpha / alpha.mean() if self.config.hierarchical else torch.ones_like(alpha))
        root = data.standardizer("root")
        self.root_mean.copy_(torch.as_tensor(root.mean[:ROOT_DIMS]))
        self.root_std.copy_(torch.as_tensor(root.std[:ROOT_DIMS]))
        self.reference.copy_(torch.as_tensor(data.quaternion_reference()))

    def use_classifiers(self, classifiers: tuple[Any, ...]) -> None:
        """The frozen classifiers of the classifier loss: each maps raw angle features and a
        mask to (logits, intermediate activations); the action's first, then the style's."""
        for classifier in classifiers:
            classifier.to(self.alpha.device).eval().requires_grad_(False)
        self.classifiers = tuple(classifiers)

    def align(self, features: torch.Tensor) -> torch.Tensor:
        """Features with every quaternion flipped into the hemisphere of ``reference``."""
        return align_quaternions(features, self.reference, ROOT_DIMS)

    def raw_features(self, features: torch.Tensor) -> torch.Tensor:
        """Features with the root values' standardisation undone (what the classifiers read)."""
        return torch.cat([features[..., :ROOT_DIMS] * self.root_std + self.root_mean, features[..., ROOT_DIMS:]], -1)

    # --- schedules ----------------------------------------------------------------------

    def kl_weight(self, step: int) -> float:
        """β: 0 while warming up, rising linearly while annealing, then 1."""
        c = self.config
        if step < c.kl_warmup:
            return 0.0
        return min(1.0, (step - c.kl_warmup + 1) / max(c.kl_anneal, 1))

    def classifier_loss_weight(self, step: int) -> float:
        """λ_CL(step): 0 until ``classifier_start``, then rising linearly to λ_CL."""
        c = self.config
        if c.classifier_weight == 0 or step < c.classifier_start:
            return 0.0
        return c.classifier_weight * min(1.0, (step - c.classifier_start + 1) / max(c.classifier_ramp, 1))

    def word_drop_probability(self, step: int) -> float:
        c = self.config
        return c.word_drop * min(1.0, step / max(c.word_drop_steps, 1))

    # --- building blocks ------------------------------------------------------------------

    def encode_word(self, poses: torch.Tensor) -> torch.Tensor:
        """w from (..., l·pose_dim) concatenated poses (identity without the word codec)."""
        return self.word_encoder(poses) if self.config.word_codec else poses

    def decode_word(self, word: torch.Tensor) -> torch.Tensor:
        """Raw decoded frames (..., l, raw_dim) of a decoded motion word."""
        raw = self.word_decoder(word) if self.config.word_codec else word
        return raw.unflatten(-1, (self.config.word_length, self.raw_dim))

    def normalise(self, raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(features (..., pose_dim) with unit quaternions, joint rotations in the loss's
        form: unit quaternions (..., J, 4) or matrices (..., J, 3, 3))."""
        root, joints = raw[..., :ROOT_DIMS], raw[..., ROOT_DIMS:]
        if self.config.rotation_output == "quaternion":
            rotations = normalize_quaternion(joints.unflatten(-1, (self.joints, 4)))
            quats = rotations
        elif self.config.rotation_output == "axis_angle":
            rotations = expmap_to_quat(joints.unflatten(-1, (self.joints, 3)))
            quats = rotations
        else:
            rotations = gram_schmidt(joints.unflatten(-1, (self.joints, 6)))
            quats = matrix_to_quat(rotations)
        return self.align(torch.cat([root, quats.flatten(-2)], -1)), rotations

    def validity(self, raw: torch.Tensor) -> torch.Tensor:
        """The rotation-validity penalty of raw frames (...,), summed over joints."""
        joints = raw[..., ROOT_DIMS:]
        if self.config.rotation_output == "quaternion":
            return quaternion_validity(joints.unflatten(-1, (self.joints, 4))).sum(-1)
        if self.config.rotation_output == "axis_angle":  # every rotation vector is a rotation
            return joints.new_zeros(joints.shape[:-1])
        return matrix_validity(joints.unflatten(-1, (self.joints, 6))).sum(-1)

    def initial_state(self, action: torch.Tensor, style: torch.Tensor, temperature: float,
                      generator: torch.Generator | RowGenerators | None = None) -> tuple[list[torch.Tensor], torch.Tensor]:
        """h_0 drawn from the Gaussian of each sequence's (action, style) pair, one per GRU
        layer, and each Gaussian's KL from N(0, I) (batch,)."""
        state, kl = self.initial(self.combination(action, style), temperature, generator)
        return list(state.chunk(self.config.state_layers, -1)), kl

    def transition(self, word_features: torch.Tensor, latent_features: torch.Tensor, a: torch.Tensor,
                   state: list[torch.Tensor]) -> list[torch.Tensor]:
        """f_h: the stacked GRU cells' new states, from f_w(w), f_z(z) and a."""
        x = torch.cat([word_features, latent_features, a], -1)
        new = []
        for cell, h in zip(self.cells, state):
            x = cell(x, h)
            new.append(x)
        return new

    def decode_latent(self, z: torch.Tensor, h: torch.Tensor, a: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(f_z(z), the decoded motion word ŵ = f_dec(f_z(z), h, a))."""
        phi_z = self.latent_features(z)
        return phi_z, self.decoder(torch.cat([phi_z, h, a], -1))

    def fed_back(self, word_hat: torch.Tensor) -> torch.Tensor:
        """The word the transition reads after generating ŵ: its frames decoded, their
        rotations normalised and sign-aligned as the real inputs are, and encoded again, so
        that it is a word of the kind the encoder makes of real motion (without the word
        codec, the frames themselves)."""
        frames = self.align(self.normalise(self.decode_word(word_hat))[0])
        return self.encode_word(frames.flatten(-2))

    def as_words(self, x: torch.Tensor) -> torch.Tensor:
        """(batch, frames, pose_dim) padded with zeros to whole words: (batch, words, l·pose_dim)."""
        l = self.config.word_length
        pad = (-x.shape[1]) % l
        if pad:
            x = F.pad(x, (0, 0, 0, pad))
        return x.reshape(x.shape[0], x.shape[1] // l, l * x.shape[2])

    # --- training objective -------------------------------------------------------------------

    def loss(self, pose: torch.Tensor, mask: torch.Tensor, action: torch.Tensor,
             style: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
        c, l = self.config, self.config.word_length
        frames = pose.shape[1]
        step = int(self.step)
        training = self.training
        if training and 0 < c.crop_frames < pose.shape[1]:
            pose, mask = random_crop(pose, mask, c.crop_frames)
            frames = c.crop_frames
        pose = self.align(pose)
        words = self.as_words(pose)
        word_mask = self.as_words(mask[..., None].float())[..., 0] > 0  # a word is real if its first frame is
        encoded = self.encode_word(words)
        phi_w = self.word_features(encoded)  # f_w of every real word at once
        a = self.control_net(self.one_hot(action, style))
        state, initial_kl = self.initial_state(action, style, 1.0)
        drop = self.word_drop_probability(step) if training else 0.0
        states, posteriors, word_hats = [], [], []
        for t in range(words.shape[1]):
            h = state[-1]
            post_mean, post_logvar = self.posterior(torch.cat([phi_w[:, t], h, a], -1))
            z = post_mean + (0.5 * post_logvar).exp() * torch.randn_like(post_mean)
            phi_z, word_hat = self.decode_latent(z, h, a)
            states.append(h)
            posteriors.append((post_mean, post_logvar))
            word_hats.append(word_hat)
            phi_word = phi_w[:, t]
            if drop > 0:  # feed back the model's own word with probability `drop`
                own = self.word_features(self.fed_back(word_hat))
                phi_word = torch.where(torch.rand(len(h), 1, device=h.device) < drop, own, phi_word)
            state = self.transition(phi_word, phi_z, a, state)

        h = torch.stack(states, 1)
        prior_mean, prior_logvar = self.prior(torch.cat([h, a[:, None].expand(-1, h.shape[1], -1)], -1))
        post_mean, post_logvar = (torch.stack(v, 1) for v in zip(*posteriors))
        kls = kl_diagonal_gaussians(post_mean, post_logvar, prior_mean, prior_logvar)
        raw = self.decode_word(torch.stack(word_hats, 1)).flatten(1, 2)[:, :frames]  # (batch, frames, raw_dim)
        features, _ = self.normalise(raw)
        reconstruction = self.frame_error(raw, pose)
        kl = masked_mean(kls, word_mask) / l  # per frame
        terms = {"reconstruction": masked_mean(reconstruction, mask), "kl": kl,
                 "validity": masked_mean(self.validity(raw), mask)}
        with torch.no_grad():  # comparable across ablations: unweighted, in degrees and standardised units
            terms["angle_degrees"] = masked_mean(self.rotation_error(features, pose).mean(-1), mask)
            terms["root_squared_error"] = masked_mean(((features - pose)[..., :ROOT_DIMS] ** 2).mean(-1), mask)
        if c.word_codec:  # the motion-word autoencoder on its own
            own_raw = self.decode_word(encoded).flatten(1, 2)[:, :frames]
            terms["word"] = masked_mean(self.frame_error(own_raw, pose), mask)
        beta = self.kl_weight(step) if training else 1.0
        terms["initial_kl"] = initial_kl.mean()
        total = terms["reconstruction"] + beta * kl + c.validity_weight * terms["validity"]
        total = total + c.initial_kl_weight * terms["initial_kl"]
        total = total + c.word_weight * terms.get("word", 0.0)
        weight = self.classifier_loss_weight(step) if training else 0.0
        if weight > 0 and self.classifiers:
            terms["classifier"] = self.classifier_loss(features, pose, mask, action, style)
            total = total + weight * terms["classifier"]
        if training:
            self.step += 1
        metrics = {name: float(value.detach()) for name, value in terms.items()}
        metrics.update(beta=beta, classifier_weight=weight, word_drop=drop)
        return total, metrics

    def rotation_error(self, features: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """The angle (degrees) of each joint's rotation from its target, (..., joints)."""
        quats = [f[..., ROOT_DIMS:].unflatten(-1, (self.joints, 4)) for f in (features, target)]
        return torch.rad2deg(2 * quaternion_distance(quats[0], normalize_quaternion(quats[1]), "d3"))

    def frame_error(self, raw: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        """(batch, frames): weight · Σ_k α_k d_k plus root_weight · the root values' squared error."""
        c = self.config
        _, rotations = self.normalise(raw)
        target_quats = target[..., ROOT_DIMS:].unflatten(-1, (self.joints, 4))
        if c.rotation_output != "matrix":  # quaternion and axis-angle outputs are compared as quaternions
            angular = hierarchical_distance(rotations, normalize_quaternion(target_quats), self.alpha, c.distance)
        else:
            angular = hierarchical_distance(rotations, quat_to_matrix(normalize_quaternion(target_quats)), self.alpha, "so3")
        root = ((raw[..., :ROOT_DIMS] - target[..., :ROOT_DIMS]) ** 2).sum(-1)
        return c.reconstruction_weight * angular + c.root_weight * root

    def classifier_loss(self, generated: torch.Tensor, real: torch.Tensor, mask: torch.Tensor,
                        action: torch.Tensor, style: torch.Tensor) -> torch.Tensor:
        """Feature matching on every intermediate activation plus cross entropy on the labels."""
        total = generated.new_zeros(())
        generated, real = self.raw_features(generated), self.raw_features(real)
        for classifier, labels in zip(self.classifiers, (action, style)):
            logits, activations = classifier(generated, mask)
            with torch.no_grad():
                _, real_activations = classifier(real, mask)
            total = total + F.cross_entropy(logits, labels)
            total = total + sum(F.mse_loss(g, r) for g, r in zip(activations, real_activations))
        return total

    # --- generation -----------------------------------------------------------------------------

    @torch.no_grad()
    def generate(self, action: torch.Tensor, style: torch.Tensor, frames: int,
                 temperature: float = 1.0, generator: torch.Generator | RowGenerators | None = None) -> torch.Tensor:
        """Sample word by word from the prior; z and h_0 are scaled by ``temperature``."""
        if frames < 1:
            raise ValueError(f"frames must be at least 1, got {frames}")
        device = self.alpha.device
        action, style = action.to(device), style.to(device)
        a = self.control_net(self.one_hot(action, style))
        state, _ = self.initial_state(action, style, temperature, generator)
        out = []
        for _ in range(math.ceil(frames / self.config.word_length)):
            h = state[-1]
            mean, logvar = self.prior(torch.cat([h, a], -1))
            noise = normal(mean.shape, generator, device=device, dtype=mean.dtype)
            z = mean + temperature * (0.5 * logvar).exp() * noise
            phi_z, word_hat = self.decode_latent(z, h, a)
            out.append(self.normalise(self.decode_word(word_hat))[0])
            state = self.transition(self.word_features(self.fed_back(word_hat)), phi_z, a, state)
        return torch.cat(out, 1)[:, :frames]
