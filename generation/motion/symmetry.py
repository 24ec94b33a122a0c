"""Left/right joint pairs, found from joint names (overridable)."""

from __future__ import annotations

import re

# (left pattern, right replacement) tried on every joint name; the first that names an
# existing joint wins. Covers the common conventions: Foot_L / foot_l, Foot.L, L_Foot /
# l_foot, LeftFoot / left_foot / LEFT_FOOT (also Mixamo's mixamorig:LeftFoot), and the
# CMU ones: LHipJoint, LThumb, LFingers, lhand, lfemur.
_NAME_RULES: tuple[tuple[str, str], ...] = (
    (r"_L$", "_R"),
    (r"_l$", "_r"),
    (r"\.L$", ".R"),
    (r"\.l$", ".r"),
    (r"^L_", "R_"),
    (r"^l_", "r_"),
    (r"Left", "Right"),
    (r"left", "right"),
    (r"LEFT", "RIGHT"),
    (r"^L(?=[A-Z])", "R"),
    (r"^l(?=[A-Za-z])", "r"),
)


def left_right_pairs(
    names: tuple[str, ...] | list[str], overrides: dict[str, str] | None = None
) -> list[tuple[int, int]]:
    """(left index, right index) for every joint pair whose names differ by side.

    ``overrides`` maps left joint names to right joint names and takes precedence, for
    rigs whose names follow no common pattern.
    """
    index = {name: i for i, name in enumerate(names)}
    pairs: dict[int, int] = {}
    for left, right in (overrides or {}).items():
        if left not in index or right not in index:
            raise ValueError(f"mirror pair ({left!r}, {right!r}) names a joint that is not in the skeleton")
        pairs[index[left]] = index[right]
    taken = set(pairs) | set(pairs.values())
    for name in names:
        if index[name] in taken:
            continue
        for pattern, replacement in _NAME_RULES:
            # A rule only counts when the partner exists: "LowerBack" is not a left joint.
            partner = re.sub(pattern, replacement, name) if re.search(pattern, name) else None
            if partner is not None and partner != name and index.get(partner) not in (None, *taken):
                pairs[index[name]] = index[partner]
                taken.update((index[name], index[partner]))
                break
    return sorted(pairs.items())


def mirror_permutation(n_joints: int, pairs: list[tuple[int, int]]) -> list[int]:
    """The joint order after swapping every left joint with its right partner."""
    order = list(range(n_joints))
    for left, right in pairs:
        order[left], order[right] = right, left
    return order
