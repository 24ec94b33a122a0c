"""The study's one display figure: named body points, and each rig's joints mapped to them.

A study is blind only if every clip looks alike apart from its motion, so every system is
drawn on the same stick figure whatever rig its motion came on. The figure is a tree of
named body points (``POINTS``) with the bone lengths of one reference skeleton
(``DisplayFigure``); ``retarget`` places a motion's frames on it.

A rig's joints are mapped to the points (``find_mapping``) by the shape of its skeleton,
which every human rig shares: the hips carry two legs and a spine, the spine a neck and
two arms; along each limb the elbow or knee is the joint its name says (Bandai-Namco,
CMU, ACCAD, Mixamo and SMPL spellings, any prefix such as ``mixamorig:``), or where no
name says, the joint between the limb's two longest bones. Joints that sit where their
parent does (CMU's zero-offset hip joints and collars) are passed over. Left and right
come from the names (``symmetry``), or where the names say nothing, from the way the toes
point. A mapping can be given or corrected point by point; ``check_mapping`` refuses one
that leaves a point out or names no joint of the rig, naming the points.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from generation.motion.root import hips_index
from generation.motion.symmetry import left_right_pairs
from generation.motion.types import Motion, Skeleton

# Each point and the point its bone hangs from, parents first. The hands (the end of the
# fingers) are drawn only where every system of a study has them (``OPTIONAL_POINTS``).
POINTS: tuple[tuple[str, str | None], ...] = (
    ("hips", None), ("spine", "hips"), ("chest", "spine"), ("neck", "chest"), ("head", "neck"),
    *((f"{side}_{part}", parent) for side in ("left", "right") for part, parent in (
        ("shoulder", "chest"), ("elbow", f"{side}_shoulder"), ("wrist", f"{side}_elbow"), ("hand", f"{side}_wrist"))),
    *((f"{side}_{part}", parent) for side in ("left", "right") for part, parent in (
        ("hip", "hips"), ("knee", f"{side}_hip"), ("ankle", f"{side}_knee"), ("toes", f"{side}_ankle"))),
)
PARENT = dict(POINTS)
OPTIONAL_POINTS = ("left_hand", "right_hand")
REQUIRED_POINTS = tuple(point for point, _ in POINTS if point not in OPTIONAL_POINTS)
FEET = ("left_ankle", "left_toes", "right_ankle", "right_toes")

# A point's bone in the figure's rest pose (facing +z, its left +x), for its skeleton's offsets.
_REST_DIRECTIONS = {
    "spine": (0, 1, 0), "chest": (0, 1, 0), "neck": (0, 1, 0), "head": (0, 1, 0),
    "shoulder": (1, -0.1, 0), "elbow": (0, -1, 0), "wrist": (0, -1, 0), "hand": (0, -1, 0),
    "hip": (1, -0.4, 0), "knee": (0, -1, 0), "ankle": (0, -1, 0), "toes": (0, -0.4, 1),
}

# What the labs call the joint of an elbow and of a knee, once prefix and side are gone.
_ELBOW_NAMES = {"elbow", "forearm", "lowerarm", "radius", "lowarm", "elbowjoint"}
_KNEE_NAMES = {"knee", "leg", "lowerleg", "tibia", "shin", "calf", "lowleg", "kneejoint"}
_HEAD_NAMES = {"head"}
# The ways a name says its side (``symmetry``'s conventions), tried in this order: the
# first that matches is the side's word, so the l of LowerLeg_L's "Lower" is not taken.
_SIDE_WORDS = tuple(map(re.compile, (r"[_.][LRlr]$", r"^[LRlr][_.]", r"(?i:left|right)", r"^[LR](?=[A-Z])",
                                      r"^[lr](?=[a-z])")))


class MappingError(ValueError):
    """A mapping that cannot place the display figure; ``missing`` lists the points it lacks."""

    def __init__(self, message: str, missing: tuple[str, ...] = ()):
        super().__init__(message)
        self.missing = missing


def base_name(name: str, sided: bool) -> str:
    """A joint's name without a lab's prefix (``mixamorig:``, ``Bip01 ``), separators, case
    and, for a joint of one side, the word for its side: ``mixamorig:LeftForeArm`` ->
    ``forearm``, ``LowerLeg_L`` -> ``lowerleg``, ``ltibia`` -> ``tibia``."""
    name = re.sub(r"^(bip0?1|def|b)[ _.-]+", "", name.rsplit(":", 1)[-1], flags=re.IGNORECASE)
    if sided:
        pattern = next((pattern for pattern in _SIDE_WORDS if pattern.search(name)), None)
        name = pattern.sub("", name, count=1) if pattern else name
    return re.sub(r"[ _.\-]", "", name).lower()


def rest_positions(skeleton: Skeleton) -> np.ndarray:
    """Joint positions (J, 3) in the rest pose (every rotation the identity)."""
    rest = np.zeros((skeleton.n_joints, 3))
    for j, p in enumerate(skeleton.parents):
        rest[j] = skeleton.offsets[j] + (rest[p] if p >= 0 else 0.0)
    return rest


class _Tree:
    """A skeleton's joints with one pose of them, for finding the body's parts."""

    def __init__(self, skeleton: Skeleton, pose: np.ndarray):
        self.skeleton, self.pose = skeleton, pose
        self.children: list[list[int]] = [[] for _ in skeleton.names]
        for j, p in enumerate(skeleton.parents):
            if p >= 0:
                self.children[p].append(j)
        size = float(np.ptp(pose, axis=0).max()) or 1.0
        self.apart = 1e-3 * size  # joints closer than this sit at one place

    def distance(self, a: int, b: int) -> float:
        return float(np.linalg.norm(self.pose[a] - self.pose[b]))

    def leaves(self, j: int) -> list[int]:
        return [j] if not self.children[j] else [leaf for c in self.children[j] for leaf in self.leaves(c)]

    def path(self, top: int, leaf: int) -> list[int]:
        """The joints from ``top`` down to ``leaf``, both included."""
        chain = [leaf]
        while chain[-1] != top:
            chain.append(int(self.skeleton.parents[chain[-1]]))
        return chain[::-1]

    def places(self, chain: list[int]) -> list[int]:
        """``chain`` without the joints that sit where the one before them does."""
        kept = [chain[0]]
        for j in chain[1:]:
            if self.distance(j, kept[-1]) > self.apart:
                kept.append(j)
        return kept

    def longest(self, top: int, child: int) -> list[int]:
        """The places from ``top`` through ``child`` to the leaf below it farthest along the bones."""
        paths = [self.places(self.path(top, leaf)) for leaf in self.leaves(child)]
        return max(paths, key=lambda chain: sum(self.distance(a, b) for a, b in zip(chain, chain[1:])))


def find_mapping(skeleton: Skeleton, pose: np.ndarray | None = None) -> dict[str, str]:
    """The rig's joint for every body point found (point -> joint name); points the rig
    has no joint for are left out (``check_mapping`` names them). ``pose`` (J, 3), y up,
    is a frame of the rig's motion (a standing one); None: the rest pose."""
    pose = rest_positions(skeleton) if pose is None else np.asarray(pose, dtype=np.float64)
    tree = _Tree(skeleton, pose)
    names = skeleton.names
    sides = {j: side for pair in left_right_pairs(names) for j, side in zip(pair, ("left", "right"))}
    hips = _hips(skeleton, tree)
    found: dict[str, int] = {"hips": hips}
    branches = [tree.longest(hips, c) for c in tree.children[hips]]
    branches = [chain for chain in branches if len(chain) > 1]
    if not branches:
        return {"hips": names[hips]}
    # Where the names say which joints are sided, the legs are the two sided branches and the
    # spine the other; else (or where they do not tell) the spine climbs highest and the legs
    # are the two branches that reach lowest.
    sided = [chain for chain in branches if chain[1] in sides]
    unsided = [chain for chain in branches if chain not in sided]
    if len(sided) == 2 and unsided:
        legs, spine_chain = sided, max(unsided, key=lambda chain: pose[chain[-1], 1])
    else:
        spine_chain = max(branches, key=lambda chain: pose[chain[-1], 1])
        legs = sorted((chain for chain in branches if chain is not spine_chain),
                      key=lambda chain: pose[chain[-1], 1])[:2]
    for chain, side in zip(legs, _sides(tree, legs, sides, "hip")):
        found.update(_limb(tree, chain, side, ("hip", "knee", "ankle", "toes"), _KNEE_NAMES, sides))
    found.update(_upper_body(tree, spine_chain, sides))
    return {point: names[j] for point, j in found.items()}


def _hips(skeleton: Skeleton, tree: _Tree) -> int:
    """The joint named hips or pelvis, else the first that carries three limbs."""
    named = hips_index(skeleton)
    if named != 0 or re.search(r"hip|pelvis", skeleton.names[0], re.IGNORECASE):
        return named
    return next((j for j, children in enumerate(tree.children) if len(children) >= 3), 0)


def _upper_body(tree: _Tree, spine_chain: list[int], sides: dict[int, str]) -> dict[str, int]:
    """The spine, chest, neck, head and arms: the arms are the two branches off the spine
    that reach farthest; the chest is where they leave it."""
    skeleton, top = tree.skeleton, spine_chain[0]
    # The head ends the spine's one unsided chain where the names tell, else its highest leaf.
    leaves = [leaf for leaf in tree.leaves(top) if leaf in _descendants(tree, spine_chain[1])]
    unsided = [leaf for leaf in leaves if not any(j in sides for j in tree.path(top, leaf))]
    column = tree.path(top, max(unsided or leaves, key=lambda leaf: tree.pose[leaf, 1]))
    off = [(j, c) for j in column[1:] for c in tree.children[j] if c not in column]  # not the legs
    named = [(j, c) for j, c in off if any(d in sides for d in _descendants(tree, c))]
    reach = {c: max(tree.distance(j, leaf) for leaf in tree.leaves(c)) for j, c in off}
    arms = named if len(named) == 2 else sorted(off, key=lambda jc: -reach[jc[1]])[:2]
    found: dict[str, int] = {}
    named_head = [j for j in column if base_name(skeleton.names[j], False) in _HEAD_NAMES]
    head = named_head[0] if named_head else column[-1]
    if len(arms) == 2:
        chest = max((j for j, _ in arms), key=column.index)
        below = tree.places(column[:column.index(chest) + 1])
        above = tree.places(column[column.index(chest):column.index(head) + 1])
        found["chest"] = chest
        if len(below) > 2:
            found["spine"] = below[-2]
        if len(above) > 2:
            found["neck"] = above[-2]
        if len(above) > 1:
            found["head"] = head
        chains = [tree.longest(j, c) for j, c in arms]
        for chain, side in zip(chains, _sides(tree, chains, sides, "shoulder")):
            found.update(_limb(tree, [chest] + chain[1:], side, ("shoulder", "elbow", "wrist", "hand"),
                               _ELBOW_NAMES, sides))
    return found


def _descendants(tree: _Tree, j: int) -> set[int]:
    return {j, *(d for c in tree.children[j] for d in _descendants(tree, c))}


def _sides(tree: _Tree, chains: list[list[int]], sides: dict[int, str], what: str) -> list[str | None]:
    """Which side each of two limbs is on: as their joints' names say, else the limb the
    left of the figure's facing (from its toes, or the rest pose's +z) is nearer."""
    said = [next((sides[j] for j in chain[1:] if j in sides), None) for chain in chains]
    if len(chains) != 2 or (said[0] and said[1] and said[0] != said[1]):
        return said if len(chains) == 2 else [None] * len(chains)
    forward = _forward(tree)
    left = np.array([forward[2], 0.0, -forward[0]])  # up x forward
    first_left = float((tree.pose[chains[0][1]] - tree.pose[chains[1][1]]) @ left) > 0
    return ["left", "right"] if first_left else ["right", "left"]


def _forward(tree: _Tree) -> np.ndarray:
    """The way the figure faces on the floor: from its heels to its toes where the feet
    are known by their shape (the two lowest leaves' last bones), else +z."""
    leaves = sorted(tree.leaves(0), key=lambda leaf: tree.pose[leaf, 1])[:2]
    vector = np.zeros(3)
    for leaf in leaves:
        parent = int(tree.skeleton.parents[leaf])
        if parent >= 0:
            vector += tree.pose[leaf] - tree.pose[parent]
    vector[1] = 0.0
    norm = np.linalg.norm(vector)
    return vector / norm if norm > tree.apart else np.array([0.0, 0.0, 1.0])


def _limb(tree: _Tree, chain: list[int], side: str | None, parts: tuple[str, str, str, str],
          joint_names: set[str], sides: dict[int, str]) -> dict[str, int]:
    """A limb's points along ``chain`` (its places from the body joint it hangs from): the
    middle joint (elbow, knee) named so, else the one between the limb's two longest
    bones; the joint before it, the one after it and the limb's end after that."""
    if side is None or len(chain) < 4:
        return {}
    names = tree.skeleton.names
    inner = chain[1:-1]
    named = [j for j in inner if base_name(names[j], j in sides) in joint_names]
    if named:
        middle = named[0]
    else:
        def score(k: int) -> float:
            return min(tree.distance(chain[k - 1], chain[k]), tree.distance(chain[k], chain[k + 1]))
        middle = chain[max(range(2, len(chain) - 1), key=score)]
    k = chain.index(middle)
    if k < 2:
        return {}
    start, middle_part, end, tip = parts
    found = {f"{side}_{start}": chain[k - 1], f"{side}_{middle_part}": middle, f"{side}_{end}": chain[k + 1]}
    if k + 2 < len(chain):
        found[f"{side}_{tip}"] = chain[-1] if tip == "hand" else chain[k + 2]
    return found


def check_mapping(skeleton: Skeleton, mapping: dict[str, str], points: tuple[str, ...] = REQUIRED_POINTS) -> None:
    """MappingError unless ``mapping`` names a joint of ``skeleton`` for each of ``points``,
    and names nothing else: the error names the points left out and the joints not in the rig."""
    if not isinstance(mapping, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in mapping.items()):
        raise MappingError("a mapping is a table of body points to joint names")
    unknown = sorted(set(mapping) - set(PARENT))
    if unknown:
        raise MappingError(f"no body point is called {', '.join(unknown)} (points: {', '.join(PARENT)})")
    missing = tuple(point for point in points if point not in mapping)
    if missing:
        raise MappingError(f"the rig's joints map to no {', '.join(missing)}: name the joint of each "
                           "(the mapping's table)", missing)
    absent = [f"{point}: {mapping[point]!r}" for point in points if mapping[point] not in skeleton.names]
    if absent:
        raise MappingError(f"the mapping names joints the rig does not have ({'; '.join(absent)})")


def complete_mapping(skeleton: Skeleton, pose: np.ndarray | None = None,
                     corrections: dict[str, str] | None = None) -> dict[str, str]:
    """``find_mapping`` with ``corrections`` (point -> joint name) over it, checked complete."""
    mapping = {**find_mapping(skeleton, pose), **(corrections or {})}
    check_mapping(skeleton, mapping)
    return mapping


def mapping_pose(motion: Motion) -> np.ndarray:
    """The frame of ``motion`` its mapping is found in: the first (y is up in every motion)."""
    return motion.positions[0]


@dataclass(frozen=True)
class DisplayFigure:
    """The figure every clip of a study is drawn on: each point's bone length (cm) to the
    point it hangs from, for every point but the hips (``PARENT``)."""

    lengths: dict[str, float]

    def __post_init__(self) -> None:
        missing = [point for point in REQUIRED_POINTS[1:] if point not in self.lengths]
        unknown = sorted(set(self.lengths) - set(PARENT) | ({"hips"} & set(self.lengths)))
        if missing or unknown:
            raise MappingError(f"a display figure needs the length of every bone: missing {', '.join(missing) or '-'}, "
                               f"not body points {', '.join(unknown) or '-'}", tuple(missing))
        bad = [point for point, length in self.lengths.items()
               if not (isinstance(length, (int, float)) and np.isfinite(length) and 0 < length < 1000)]
        if bad:
            raise MappingError(f"bone lengths must be positive cm under 10 m: {', '.join(bad)}")

    @property
    def points(self) -> tuple[str, ...]:
        return tuple(point for point, _ in POINTS if point == "hips" or point in self.lengths)

    @property
    def leg_length(self) -> float:
        """Hip to knee to ankle, averaged over the sides: what the root's height scales by."""
        return leg_length(lambda point: self.lengths[point])

    def with_points(self, points: set[str]) -> "DisplayFigure":
        """The figure without the optional points not in ``points``."""
        return DisplayFigure({p: v for p, v in self.lengths.items() if p in points or p not in OPTIONAL_POINTS})

    def skeleton(self) -> Skeleton:
        """The figure as a skeleton in its rest pose (facing +z), the points as joint names."""
        points = self.points
        offsets = np.zeros((len(points), 3))
        for j, point in enumerate(points[1:], start=1):
            direction = np.array(_REST_DIRECTIONS[point.split("_")[-1]], dtype=np.float64)
            if point.startswith("right_"):
                direction[0] = -direction[0]
            offsets[j] = self.lengths[point] * direction / np.linalg.norm(direction)
        parents = np.array([-1] + [points.index(PARENT[point]) for point in points[1:]])
        return Skeleton(points, parents, offsets)

    def to_dict(self) -> dict:
        return {"lengths": {point: round(float(length), 4) for point, length in self.lengths.items()}}

    @classmethod
    def from_dict(cls, data: dict) -> "DisplayFigure":
        if not isinstance(data, dict) or not isinstance(data.get("lengths"), dict):
            raise MappingError("a display figure is a table of bone lengths")
        return cls(dict(data["lengths"]))

    @classmethod
    def of_motion(cls, motion: Motion, mapping: dict[str, str]) -> "DisplayFigure":
        """The figure with ``motion``'s bone lengths (each the median over its frames), on
        the points ``mapping`` names."""
        check_mapping(motion.skeleton, mapping)
        index = {point: motion.skeleton.index(joint) for point, joint in mapping.items()}
        lengths = {}
        for point, parent in POINTS[1:]:
            if point in index and parent in index:
                bone = motion.positions[:, index[point]] - motion.positions[:, index[parent]]
                lengths[point] = float(np.median(np.linalg.norm(bone, axis=-1)))
        return cls(lengths)


def leg_length(length) -> float:
    """Hip to knee to ankle averaged over both legs, ``length(point)`` each point's bone."""
    return sum(length(f"{side}_{part}") for side in ("left", "right") for part in ("knee", "ankle")) / 2


__all__ = ["DisplayFigure", "FEET", "MappingError", "OPTIONAL_POINTS", "PARENT", "POINTS", "REQUIRED_POINTS",
           "base_name", "check_mapping", "complete_mapping", "find_mapping", "leg_length", "mapping_pose",
           "rest_positions"]
