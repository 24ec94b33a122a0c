"""Unit and up-axis detection exist once (``measures.units``): at most one unit makes any
figure human-sized, and ``generation`` (from a BVH skeleton) and ``analysis`` (from motion
arrays) read the same real figure in the same unit, also at the edge of the window, with
the same up axis on real rigs, and refuse the same scale with the same words on their
command lines.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from analysis.cli import main as analysis_main
from analysis.motion.motion_io import SystemClips
from analysis.motion.centimetres import to_centimetres_y_up
from generation.cli import main as generation_main
from generation.motion.bvh import load_motion, motion_to_bvh, write_bvh
from generation.motion.types import Motion, Skeleton
from generation.motion.unit_detection import choose_units
from generation.motion.skeleton_units import detect_up
from measures.units import HUMAN_HEIGHT_CM, UNITS, Z_UP_TO_Y_UP, parse_scale, unit_for_height, up_axis
from tests.lab_rigs import LAB_RIGS


def test_the_human_window_is_narrower_than_any_two_units_so_at_most_one_fits():
    closest = min(max(a, b) / min(a, b) for a, b in itertools.combinations(UNITS.values(), 2))
    assert HUMAN_HEIGHT_CM[1] / HUMAN_HEIGHT_CM[0] < closest
    for height in np.geomspace(1e-3, 1e5, 2000):
        fits = [unit for unit, factor in UNITS.items() if HUMAN_HEIGHT_CM[0] <= height * factor <= HUMAN_HEIGHT_CM[1]]
        assert len(fits) <= 1 and unit_for_height(height) == (fits[0] if fits else None)


def scaled(motion: Motion, factor: float) -> Motion:
    skeleton = motion.skeleton
    return Motion(motion.positions * factor, motion.fps,
                  Skeleton(skeleton.names, skeleton.parents, skeleton.offsets * factor,
                           {j: o * factor for j, o in skeleton.end_sites.items()}),
                  motion.rotations, None if motion.translations is None else motion.translations * factor)


@pytest.mark.parametrize("factor, unit", [(0.78, "cm"), (1.0, "cm"), (0.0078, "m"), (0.78 / 2.54, "in")],
                         ids=["a small person in cm", "the actor in cm", "a small person in m", "a small person in in"])
def test_generation_and_analysis_read_a_real_figure_in_the_same_unit(factor, unit, clip_path, tmp_path):
    """0.78 of the actor's size (a 1.14 m skeleton, a figure 1.04 m tall): both inside
    the one window, where generation's own 1.2 m bound once assumed centimetres instead."""
    walk = scaled(load_motion(clip_path("walk_normal_001")), factor)
    bvh = write_bvh(motion_to_bvh(walk), tmp_path / "walk.bvh")
    choice = choose_units([bvh])
    assert choice.units.scale == UNITS[unit] and "unit detected from the skeleton's size" in choice.description
    clips = {"NAT": SystemClips("NAT", walk.fps, walk.skeleton.names, walk.skeleton.parents, walk.skeleton.offsets,
                                [walk.positions])}
    converted, said = to_centimetres_y_up(clips)
    assert said.startswith(f"motion units: {unit}, y up")
    np.testing.assert_allclose(converted["NAT"].clips[0], walk.positions * UNITS[unit])


def rig_motion(rig: str, clip_path, lab_rigs) -> Motion:
    if rig == "shared data":
        return load_motion(clip_path("walk_normal_001"))
    return load_motion(lab_rigs[rig] / "take_01.bvh", UNITS[LAB_RIGS[rig].unit])


@pytest.mark.parametrize("rig", ["shared data", *sorted(LAB_RIGS)])
@pytest.mark.parametrize("up", ["y", "z"])
def test_generation_and_analysis_find_the_same_up_axis_on_real_rigs(rig, up, clip_path, lab_rigs):
    """The real takes as they are (y up) and turned z up: the BVH reader's rule (on the
    body below the hips) and the analysis' (on every joint but a reference on the floor)
    are one rule, and both find the axis the take stands along."""
    motion = rig_motion(rig, clip_path, lab_rigs)
    # Z_UP_TO_Y_UP maps z-up points to y-up ones (p -> R p); its transpose turns them back.
    positions = motion.positions @ Z_UP_TO_Y_UP if up == "z" else motion.positions
    turned = Motion(positions, motion.fps, motion.skeleton)
    assert detect_up(turned) == up
    skeleton = motion.skeleton
    clips = {"NAT": SystemClips("NAT", motion.fps, skeleton.names, skeleton.parents, skeleton.offsets, [positions])}
    converted, said = to_centimetres_y_up(clips, scale=1.0)
    assert said.startswith(f"motion units: cm, {up} up")
    np.testing.assert_allclose(converted["NAT"].clips[0], motion.positions, atol=1e-9)


def test_the_up_axis_is_where_a_figure_is_tallest_in_most_frames():
    standing = np.zeros((5, 3, 3))
    standing[:, 1, 1], standing[:, 2, 1] = 90.0, 170.0  # hips and head above a foot, y up
    lying = standing[:2][:, :, [0, 2, 1]]  # two frames with the figure along z
    assert up_axis([standing]) == "y" and up_axis([standing, lying]) == "y"
    assert up_axis([standing[:, :, [0, 2, 1]]]) == "z"
    with pytest.raises(ValueError, match=r"non-empty \(frames, joints, 3\) arrays"):
        up_axis([np.zeros((0, 3, 3))])


@pytest.mark.parametrize("text, scale", [("auto", None), ("M", 100.0), (" cmu ", 2.54 / 0.45), ("2.5", 2.5)])
def test_a_scale_is_auto_a_unit_or_a_factor(text, scale):
    assert parse_scale(text) == scale


@pytest.mark.parametrize("text, message", [
    ("furlongs", "scale must be auto, a unit (mm, cm, in, cmu, ft, m) or a number, got 'furlongs'"),
    ("0", "scale must be a positive number of centimetres per file unit, got 0.0"),
    ("nan", "scale must be a positive number of centimetres per file unit, got nan"),
    ("-inf", "scale must be a positive number of centimetres per file unit, got -inf"),
])
def test_both_command_lines_refuse_a_scale_with_the_same_words(text, message, clip_path, tmp_path, capsys):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        parse_scale(text)
    for main, command in ((generation_main, ["info", str(clip_path("walk_normal_001"))]),
                          (analysis_main, ["objective", str(tmp_path / "motion"), "--out", str(tmp_path / "out")])):
        with pytest.raises(SystemExit) as exit_:
            main([*command, f"--scale={text}"])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and f"argument --scale: {message}" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
