"""Left/right joint pairs, found from joint names (overridable)."""

from __future__ import annotations

import re

# (left pattern, right replacement) tried on every joint name; the first that names an
# existing joint wins. Covers Foot_L, LeftFoot, left_foot, L_Foot, Foot.L, lFoot.
_NAME_RULES: tuple[tuple[str, str], ...] = (
    (r"_L$", "_R"),
    (r"\.L$", ".R"),
    (r"^L_", "R_"),
    (r"Left", "Right"),
    (r"left", "right"),
    (r"LEFT", "RIGHT"),
    (r"^l(?=[A-Z])", "r"),
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
    for name in names:
        for pattern, replacement in _NAME_RULES:
            if re.search(pattern, name):
                partner = re.sub(pattern, replacement, name)
                if partner in index and index[name] not in pairs:
                    pairs[index[name]] = index[partner]
                break
    return sorted(pairs.items())


def mirror_permutation(n_joints: int, pairs: list[tuple[int, int]]) -> list[int]:
    """The joint order after swapping every left joint with its right partner."""
    order = list(range(n_joints))
    for left, right in pairs:
        order[left], order[right] = right, left
    return order
