"""The study's display figure: one real walk written on other labs' rigs (CMU's, ACCAD's,
a Mixamo-named one and one whose names say nothing, ``tests/lab_rigs.py``) is mapped to
the same body points and, retargeted, placed and drawn alike on every rig."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from generation.gallery import GalleryOptions, render_clip, with_figure
from generation.motion.clip_files import load_body_motion
from generation.motion.types import Motion, Skeleton
from generation.render import Camera
from generation.render.display_figure import (DisplayFigure, MappingError, base_name, check_mapping,
                                              complete_mapping, find_mapping)
from generation.render.draw import FrameDrawer
from generation.render.retarget import retarget
from measures.units import UNITS
from tests.lab_rigs import FIGURE_RIGS, LAB_RIGS, write_lab_take

FPS = 20.0
SECONDS = 4.0
TAKE = "dataset-2_walk_masculine_001.bvh"
RIGS = {**LAB_RIGS, **FIGURE_RIGS}


@pytest.fixture(scope="module")
def take(motion_data_2):
    """The Bandai-Namco walk every rig is written from, as NAT reads it."""
    return load_body_motion(motion_data_2 / "data" / TAKE, FPS, SECONDS)


@pytest.fixture(scope="module")
def rigs(motion_data_2, tmp_path_factory) -> dict[str, Motion]:
    """The same walk on every rig, read in its lab's unit at the study's frame rate."""
    folder = tmp_path_factory.mktemp("figure-rigs")
    return {name: load_body_motion(write_lab_take(motion_data_2 / "data" / TAKE, rig, folder / f"{name}.bvh"),
                                   FPS, SECONDS, scale=UNITS[rig.unit])
            for name, rig in RIGS.items()}


@pytest.fixture(scope="module")
def figure(take) -> DisplayFigure:
    return DisplayFigure.of_motion(take, complete_mapping(take.skeleton, take.positions[0]))


def test_every_rig_maps_its_joints_to_the_body_points_by_their_names(take, rigs):
    expected = {
        "bandai-namco": {"hips": "Hips", "spine": "Spine", "chest": "Chest", "neck": "Neck", "head": "Head",
                         "left_shoulder": "UpperArm_L", "left_elbow": "LowerArm_L", "left_wrist": "Hand_L",
                         "left_hip": "UpperLeg_L", "left_knee": "LowerLeg_L", "left_ankle": "Foot_L",
                         "left_toes": "Toes_L"},
        "cmu": {"hips": "Hips", "spine": "Chest", "chest": "Chest2", "neck": "Neck", "head": "Head",
                "left_shoulder": "LeftShoulder", "left_elbow": "LeftElbow", "left_wrist": "LeftWrist",
                "left_hand": "LFingers", "left_hip": "LeftHip", "left_knee": "LeftKnee", "left_ankle": "LeftAnkle",
                "left_toes": "LeftToe"},
        "accad": {"hips": "root", "spine": "upperback", "chest": "thorax", "neck": "neck", "head": "head",
                  "left_shoulder": "lhumerus", "left_elbow": "lradius", "left_wrist": "lhand", "left_hip": "lfemur",
                  "left_knee": "ltibia", "left_ankle": "lfoot", "left_toes": "ltoes"},
        "mixamo": {"hips": "mixamorig:Hips", "spine": "mixamorig:Spine", "chest": "mixamorig:Spine2",
                   "neck": "mixamorig:Neck", "head": "mixamorig:Head", "left_shoulder": "mixamorig:LeftArm",
                   "left_elbow": "mixamorig:LeftForeArm", "left_wrist": "mixamorig:LeftHand",
                   "left_hand": "mixamorig:LeftHandMiddle1", "left_hip": "mixamorig:LeftUpLeg",
                   "left_knee": "mixamorig:LeftLeg", "left_ankle": "mixamorig:LeftFoot",
                   "left_toes": "mixamorig:LeftToeBase"},
    }
    motions = {"bandai-namco": take, **rigs}
    for name, left in expected.items():
        motion = motions[name]
        mapping = complete_mapping(motion.skeleton, motion.positions[0])
        assert {point: joint for point, joint in mapping.items() if not point.startswith("right_")} == left, name
        assert len(mapping) == len(left) + sum(point.startswith("left_") for point in left), name


def test_a_rig_whose_names_say_nothing_is_mapped_by_its_shape(rigs):
    cmu, nameless = rigs["cmu"], rigs["nameless"]
    named = complete_mapping(cmu.skeleton, cmu.positions[0])
    by_shape = complete_mapping(nameless.skeleton, nameless.positions[0])
    assert by_shape == {point: nameless.skeleton.names[cmu.skeleton.index(joint)] for point, joint in named.items()}


def test_the_same_walk_on_every_rig_places_the_display_figure_within_a_centimetre_at_every_frame(take, rigs, figure):
    reference = retarget(take, complete_mapping(take.skeleton, take.positions[0]), figure)
    assert reference.skeleton.names == figure.points and len(figure.points) == 19  # no hands: Bandai-Namco has none
    for name, motion in rigs.items():
        placed = retarget(motion, find_mapping(motion.skeleton, motion.positions[0]), figure)
        assert placed.skeleton.names == reference.skeleton.names, name
        frames = min(placed.n_frames, reference.n_frames)
        error = np.linalg.norm(placed.positions[:frames] - reference.positions[:frames], axis=-1)
        assert error.max() < 1.0, (name, error.max())


def test_the_figure_has_the_reference_bone_lengths_and_stands_on_the_floor(take, figure):
    placed = retarget(take, complete_mapping(take.skeleton, take.positions[0]), figure)
    skeleton = placed.skeleton
    for point, length in figure.lengths.items():
        j = skeleton.index(point)
        bone = placed.positions[:, j] - placed.positions[:, skeleton.parents[j]]
        np.testing.assert_allclose(np.linalg.norm(bone, axis=-1), length, rtol=1e-9, err_msg=point)
    feet = placed.positions[:, [skeleton.index(p) for p in ("left_toes", "right_toes", "left_ankle", "right_ankle")], 1]
    original = take.positions[:, [take.skeleton.index(j) for j in ("Toes_L", "Toes_R", "Foot_L", "Foot_R")], 1]
    assert abs(np.quantile(feet.min(axis=1), 0.05) - np.quantile(original.min(axis=1), 0.05)) < 0.5


def test_a_taller_performer_at_another_frame_rate_is_drawn_as_the_same_figure(take, figure):
    """A performer 15 % taller, captured at 60 fps: only directions reach the figure, and the
    root's height is scaled by the legs, so the figure's pose is the same."""
    mapping = complete_mapping(take.skeleton, take.positions[0])
    taller = Motion(take.positions * 1.15, FPS, replace(take.skeleton, offsets=take.skeleton.offsets * 1.15))
    fast = Motion(np.repeat(taller.positions, 3, axis=0)[:-2], 3 * FPS, taller.skeleton)  # every frame thrice
    placed, reference = retarget(fast, mapping, figure, fps=FPS), retarget(take, mapping, figure)
    assert placed.fps == FPS and placed.n_frames == reference.n_frames
    relative = placed.positions - placed.positions[:, :1]
    np.testing.assert_allclose(relative, reference.positions - reference.positions[:, :1], atol=1e-6)
    np.testing.assert_allclose(placed.positions[:, 0, 1], reference.positions[:, 0, 1], atol=0.5)


def test_the_rendered_frames_of_one_walk_on_two_rigs_differ_by_rendering_noise_only(rigs, figure):
    """The measure: the mean absolute difference of the frames' pixels (0-255, every channel),
    and the share of pixels that differ by more than 16 levels. Drawn on their own skeletons
    the two rigs differ visibly; on the display figure by no more than antialiasing."""
    def frames(motion, retargeted: bool) -> np.ndarray:
        if retargeted:
            motion = retarget(motion, find_mapping(motion.skeleton, motion.positions[0]), figure)
        drawer = FrameDrawer(motion, Camera(), (320, 240))
        return np.stack([drawer.frame(k) for k in range(0, len(drawer), 8)]).astype(np.int16)

    def differences(a, b) -> tuple[float, float]:
        frames_ = min(len(a), len(b))
        delta = np.abs(a[:frames_] - b[:frames_])
        return float(delta.mean()), float((delta.max(axis=-1) > 16).mean())

    cmu, accad = rigs["cmu"], rigs["accad"]
    own_mean, own_share = differences(frames(cmu, False), frames(accad, False))
    mean, share = differences(frames(cmu, True), frames(accad, True))
    # Measured: on their own rigs 0.063 levels and 0.07 % of pixels (the figure covers about 3 % of
    # the frame); on the display figure 0.0014 levels and 0.003 % (edge pixels of a line's antialiasing).
    assert own_mean > 0.03 and own_share > 5e-4, (own_mean, own_share)
    assert mean < 0.01 and share < 1e-4, (mean, share)


def test_a_rig_missing_a_body_point_is_refused_naming_it(take):
    # The head hung straight from the chest: the rig has no neck.
    names = list(take.skeleton.names)
    neck, head = names.index("Neck"), names.index("Head")
    keep = [j for j in range(len(names)) if j != neck]
    parents = [int(take.skeleton.parents[j]) for j in keep]
    parents[keep.index(head)] = names.index("Chest")
    parents = [keep.index(p) if p >= 0 else -1 for p in parents]
    offsets = take.skeleton.offsets[keep].copy()
    offsets[keep.index(head)] += take.skeleton.offsets[neck]
    skeleton = Skeleton(tuple(names[j] for j in keep), np.array(parents), offsets)
    with pytest.raises(MappingError, match=r"map to no neck: name the joint") as refused:
        complete_mapping(skeleton, take.positions[0, keep])
    assert refused.value.missing == ("neck",)
    # Named by hand (the researcher's correction), the head's parent stands in for it.
    assert complete_mapping(skeleton, take.positions[0, keep], {"neck": "Chest"})["neck"] == "Chest"


def test_a_corrected_mapping_naming_no_joint_of_the_rig_is_refused_naming_the_point(take):
    mapping = complete_mapping(take.skeleton, take.positions[0])
    with pytest.raises(MappingError, match=r"joints the rig does not have \(left_elbow: 'LeftElbow'\)"):
        check_mapping(take.skeleton, {**mapping, "left_elbow": "LeftElbow"})
    with pytest.raises(MappingError, match=r"no body point is called tail"):
        check_mapping(take.skeleton, {**mapping, "tail": "Hips"})


@pytest.mark.parametrize(("name", "base"), [("mixamorig:LeftForeArm", "forearm"), ("LowerLeg_L", "lowerleg"),
                                            ("ltibia", "tibia"), ("left_knee", "knee"), ("L_Knee", "knee"),
                                            ("Foot.R", "foot"), ("RightElbow", "elbow")])
def test_a_joints_base_name_drops_prefix_side_and_separators(name, base):
    assert base_name(name, sided=True) == base


def test_a_display_figure_round_trips_through_its_description_and_refuses_a_missing_bone(figure):
    assert DisplayFigure.from_dict(figure.to_dict()).lengths == pytest.approx(figure.lengths, abs=1e-4)
    lengths = dict(figure.lengths)
    del lengths["neck"]
    with pytest.raises(MappingError, match="missing neck"):
        DisplayFigure(lengths)


def test_the_gallery_draws_one_walk_on_two_rigs_and_on_its_own_as_the_same_figure(motion_data_2, tmp_path, figure):
    """The gallery's clips are drawn on the figure of the first clip it draws (here the
    Bandai-Namco walk itself), so the same walk written on CMU's and ACCAD's rigs gives the
    same contact sheet as the walk's own file, to rendering noise: the mean absolute
    difference of the sheets' pixels (0-255, every channel) and the share of pixels that
    differ by more than 16 levels."""
    source = motion_data_2 / "data" / TAKE
    options = with_figure(GalleryOptions(fps=FPS, seconds=SECONDS, size=(320, 240)), [source])
    assert options.figure is not None and options.figure.points == figure.points
    for point, length in figure.lengths.items():
        assert abs(options.figure.lengths[point] - length) < 1e-3, point
    options = GalleryOptions.from_dict(options.to_dict())  # as a worker receives them
    sheets = {}
    for name in ("bandai-namco", "cmu", "accad"):
        folder = tmp_path / name
        folder.mkdir()
        if name == "bandai-namco":
            bvh, scale = source, None
        else:
            bvh, scale = write_lab_take(source, RIGS[name], folder / TAKE), UNITS[RIGS[name].unit]
        entry = render_clip(bvh, folder, replace(options, scale=scale))
        sheets[name] = np.asarray(Image.open(folder / entry["sheet"]).convert("RGB"), dtype=np.int16)
    for name in ("cmu", "accad"):
        delta = np.abs(sheets[name] - sheets["bandai-namco"])
        mean, share = float(delta.mean()), float((delta.max(axis=-1) > 16).mean())
        # Measured: each drawn on its own rig (the gallery before it drew the figure) 3.7 levels and
        # 7.2 % of the pixels; on the figure 0.0006 (CMU) and 0.0012 (ACCAD) levels, 0.001 % and 0.003 %.
        assert mean < 0.01 and share < 1e-4, (name, mean, share)
