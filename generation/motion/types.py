"""The shared data types of the project: a skeleton and a motion on it.

Everything that produces or consumes motion (the BVH reader, every model, the renderer,
the objective metrics) speaks in these two types. Units: centimetres, seconds, y up.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Skeleton:
    """A kinematic tree.

    ``parents[j]`` is the index of joint j's parent, -1 for the root; parents always come
    before their children. ``offsets[j]`` is joint j's rest translation from its parent
    (cm). ``end_sites`` maps a joint index to the offsets of the BVH End Sites below it;
    End Sites are kept for faithful BVH writing but are not joints (they carry no
    channels and are not part of ``Motion.positions``).
    """

    names: tuple[str, ...]
    parents: np.ndarray  # (J,) int
    offsets: np.ndarray  # (J, 3) float, cm
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)  # joint -> (k, 3)

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=np.float64)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        n = len(self.names)
        if n == 0:  # everything that walks a skeleton starts at its root
            raise ValueError("a skeleton needs at least one joint, its root")
        if parents.shape != (n,) or offsets.shape != (n, 3):
            raise ValueError(
                f"skeleton of {n} joints needs parents of shape ({n},) and offsets of "
                f"shape ({n}, 3), got {parents.shape} and {offsets.shape}"
            )
        if len(set(self.names)) != n:
            raise ValueError("skeleton joint names must be unique")
        for j, p in enumerate(parents):
            if not (p == -1 if j == 0 else 0 <= p < j):
                raise ValueError(
                    f"joint {self.names[j]!r} has parent index {p}; the root must come "
                    "first and every parent must come before its children"
                )

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """The index of the joint called ``name`` (ValueError naming it if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(
                f"no joint named {name!r} in the skeleton (joints: {', '.join(self.names)})"
            ) from None

    def bones(self) -> list[tuple[int, int]]:
        """(parent, child) pairs, one per non-root joint."""
        return [(int(p), j) for j, p in enumerate(self.parents) if p >= 0]

    def bone_lengths(self) -> np.ndarray:
        """Rest length of each bone in ``bones()`` order (cm)."""
        return np.linalg.norm(self.offsets[1:], axis=-1)

    def subtree(self, root: int) -> tuple["Skeleton", list[int]]:
        """The skeleton below (and including) joint ``root``, and the kept joint indices."""
        keep = [root]
        for j in range(root + 1, self.n_joints):
            if self.parents[j] in keep:
                keep.append(j)
        new_index = {old: new for new, old in enumerate(keep)}
        skeleton = Skeleton(
            names=tuple(self.names[j] for j in keep),
            parents=np.array([-1] + [new_index[int(self.parents[j])] for j in keep[1:]]),
            offsets=self.offsets[keep],
            end_sites={new_index[j]: o for j, o in self.end_sites.items() if j in new_index},
        )
        return skeleton, keep

    def to_dict(self) -> dict:
        """A JSON-serialisable description (used in checkpoints and dataset caches)."""
        return {
            "names": list(self.names),
            "parents": self.parents.tolist(),
            "offsets": self.offsets.tolist(),
            "end_sites": {str(j): np.asarray(o).tolist() for j, o in self.end_sites.items()},
        }

    @classmethod
    def from_dict(cls, data: dict) -> "Skeleton":
        return cls(
            names=tuple(data["names"]),
            parents=np.asarray(data["parents"]),
            offsets=np.asarray(data["offsets"], dtype=np.float64),
            end_sites={
                int(j): np.asarray(o, dtype=np.float64).reshape(-1, 3)
                for j, o in data.get("end_sites", {}).items()
            },
        )


@dataclass(frozen=True)
class Motion:
    """Joint positions over time on a skeleton.

    ``positions`` is (frames, joints, 3) in centimetres with y up. ``rotations`` are the
    optional local joint rotations as unit quaternions (w, x, y, z), (frames, joints, 4),
    and ``translations`` the local joint translations (frames, joints, 3), the skeleton's
    offsets except where a joint's translation is animated (the hips, usually): both are
    present when the motion came from joint angles (BVH, angle-based models) and absent
    for position-only models.
    """

    positions: np.ndarray
    fps: float
    skeleton: Skeleton
    rotations: np.ndarray | None = None
    translations: np.ndarray | None = None

    def __post_init__(self) -> None:
        positions = np.asarray(self.positions, dtype=np.float64)
        object.__setattr__(self, "positions", positions)
        j = self.skeleton.n_joints
        if positions.ndim != 3 or positions.shape[1:] != (j, 3):
            raise ValueError(
                f"positions must have shape (frames, {j}, 3) for this skeleton, "
                f"got {positions.shape}"
            )
        if len(positions) == 0:
            raise ValueError("a motion needs at least one frame")
        if not np.isfinite(positions).all():
            frame = int(np.argwhere(~np.isfinite(positions))[0, 0])
            raise ValueError(f"motion positions contain NaN or infinity (first at frame {frame})")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be positive and finite, got {self.fps}")
        if self.rotations is not None and np.shape(self.rotations) != (len(positions), j, 4):
            raise ValueError(f"rotations must have shape ({len(positions)}, {j}, 4)")
        if (self.rotations is None) != (self.translations is None):
            raise ValueError("rotations and translations come together or not at all")
        if self.translations is not None and np.shape(self.translations) != (len(positions), j, 3):
            raise ValueError(f"translations must have shape ({len(positions)}, {j}, 3)")

    @property
    def n_frames(self) -> int:
        return len(self.positions)

    @property
    def duration(self) -> float:
        """Length in seconds."""
        return self.n_frames / self.fps
