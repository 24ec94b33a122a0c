"""The mismatch rule of appropriateness studies, on the real data's held-out controls and
on constructed ones: same length, comparable speed, a different shape, seeded draws."""

from __future__ import annotations


import numpy as np
import pytest

from generation.control import AttributeControl, PathControl, held_out_paths, preset_path
from generation.mismatch import (ATTENTION_GAP, SHAPE_GAP, SPEED_BAND, SPEED_FLOOR, TURN_BAND,
                                 choose_attention_checks, choose_mismatches)
from generation.motion.dataset import build_dataset
from generation.motion.dataset_options import DatasetOptions

STYLES = ("normal", "elderly", "exhausted")
CONTENTS = ("walk", "walk-turn-left", "walk-turn-right")


@pytest.fixture(scope="module")
def held_out(motion_data_2, tmp_path_factory) -> list[PathControl]:
    """The held-out 4-s controls of dataset-2's walks and turns in three styles (fast
    walkers, slow ones and turns both ways; a few hundred takes, so it builds in seconds)."""
    folder = tmp_path_factory.mktemp("walks")
    (folder / "data").mkdir()
    (folder / "cfg").symlink_to(motion_data_2 / "cfg")
    for content in CONTENTS:
        for style in STYLES:
            for take in (motion_data_2 / "data").glob(f"dataset-2_{content}_{style}_*"):
                (folder / "data" / take.name).symlink_to(take)
    dataset = build_dataset(folder, DatasetOptions(), cache_dir=tmp_path_factory.mktemp("cache"), progress=False)
    return held_out_paths(dataset, seconds=4)


def speed(control: PathControl) -> float:
    return float(np.mean(np.sqrt(control.velocities[:, 0] ** 2 + control.velocities[:, 1] ** 2)))


def turning(control: PathControl) -> float:
    return float(np.degrees(np.sum(control.velocities[1:, 2]) / control.fps))


def largest_departure(shown: PathControl, partner: PathControl, points: int = 64) -> float:
    """Written apart from the module: both floor paths resampled at equal shares of their
    lengths and scaled to length 1, then the largest distance between matching points."""
    def unit_shape(control: PathControl) -> np.ndarray:
        xz = control.path().xz
        travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xz, axis=0).T))])
        at = np.linspace(0.0, travelled[-1], points)
        return np.stack([np.interp(at, travelled, xz[:, i]) for i in (0, 1)], axis=1) / travelled[-1]

    return float(np.max(np.hypot(*(unit_shape(shown) - unit_shape(partner)).T)))


def test_held_out_controls_get_partners_as_long_as_fast_and_differently_shaped(held_out):
    takes = {c.name for c in held_out}
    pairs = choose_mismatches(held_out, seed=3, takes=takes)
    by_name = {c.name: c for c in held_out}
    paired = [m for m in pairs if m.partner is not None]
    assert len(paired) >= 0.8 * len(held_out), [m.reason for m in pairs if m.partner is None]
    for mismatch in paired:
        shown, partner = by_name[mismatch.shown], mismatch.partner
        assert partner.name in takes and partner.name != shown.name  # another take: NAT has its clip
        assert partner.n_frames == shown.n_frames
        assert np.array_equal(partner.velocities, by_name[partner.name].velocities[:shown.n_frames])
        assert abs(speed(partner) - speed(shown)) <= max(SPEED_BAND * speed(shown), SPEED_FLOOR) + 1e-9
        departure = largest_departure(shown, partner)
        assert departure >= SHAPE_GAP - 1e-9
        assert mismatch.shape_gap == pytest.approx(departure, rel=1e-9)
    within = [m for m in paired if m.reason.startswith("drawn among")]
    assert len(within) >= len(paired) / 2
    for mismatch in within:
        assert fits_every_band(by_name[mismatch.shown], mismatch.partner)
    for mismatch in (m for m in paired if m not in within):  # closest in turning only where nothing fits every band
        shown = by_name[mismatch.shown]
        assert not any(fits_every_band(shown, PathControl(c.velocities[:shown.n_frames], c.fps, c.name))
                       for c in held_out if c.name != shown.name and c.n_frames >= shown.n_frames)


def fits_every_band(shown: PathControl, partner: PathControl) -> bool:
    departure = largest_departure(shown, partner)
    return (abs(speed(partner) - speed(shown)) <= max(SPEED_BAND * speed(shown), SPEED_FLOOR)
            and SHAPE_GAP <= departure < ATTENTION_GAP
            and abs(abs(turning(partner)) - abs(turning(shown))) <= TURN_BAND)


def test_the_draw_is_seeded_and_does_not_depend_on_the_order_of_the_controls(held_out):
    def partners(controls, seed):
        return {m.shown: m.partner and m.partner.name for m in choose_mismatches(controls, seed=seed)}

    first = partners(held_out, 0)
    assert partners(held_out, 0) == first
    assert partners(list(reversed(held_out)), 0) == first
    assert any(partners(held_out, seed) != first for seed in (1, 2, 3))
    without_one = partners(held_out[1:], 0)  # the others keep their partner unless it was the one removed
    assert all(partner == first[shown] for shown, partner in without_one.items() if first[shown] != held_out[0].name)


def test_attention_checks_pair_a_turn_with_a_path_departing_far_more(held_out):
    regular = {m.shown: m for m in choose_mismatches(held_out)}
    checks = choose_attention_checks(held_out)
    by_name = {c.name: c for c in held_out}
    turns = [m for m in checks if "walk-turn" in m.shown]
    assert turns and all(m.partner is not None and regular[m.shown].partner is not None for m in turns)
    more = 0
    for check in turns:
        shown = by_name[check.shown]
        assert check.partner.n_frames == shown.n_frames
        assert largest_departure(shown, check.partner) >= ATTENTION_GAP
        assert check.shape_gap >= regular[check.shown].shape_gap
        if regular[check.shown].shape_gap < ATTENTION_GAP:  # no other partner but a glaring one
            more += 1
            assert check.shape_gap > regular[check.shown].shape_gap
        assert np.sign(turning(check.partner)) != np.sign(turning(shown))  # it turns the other way
    assert more >= 0.8 * len(turns)


def test_a_take_is_paired_with_takes_only_and_a_control_standing_still_with_none():
    fps = 20.0
    circle, zigzag = preset_path("walk-circle", fps), preset_path("walk-zigzag", fps)
    take = PathControl(circle.velocities * [1, 1, -1], fps, "take-turning-right")  # the circle mirrored
    other_take = PathControl(np.tile([110.0, 0.0, 0.0], (80, 1)), fps, "take-straight")
    controls = [take, other_take, circle, zigzag, preset_path("stand-still", fps)]
    pairs = {m.shown: m for m in choose_mismatches(controls, takes={"take-turning-right", "take-straight"})}
    assert pairs["take-turning-right"].partner.name == "take-straight"  # not the circle, though it fits better
    assert pairs["walk-circle"].partner.name == "take-turning-right"  # the circle the other way round
    assert pairs["stand-still"].partner is None
    assert pairs["stand-still"].reason == "no other control of the study as long is within the speed band"
    still = {m.shown: m for m in choose_attention_checks(controls)}["stand-still"]
    assert still.partner.name in {"take-turning-right", "take-straight", "walk-circle", "walk-zigzag"}


def test_labels_are_paired_with_another_label_pair_of_the_same_length():
    fps = 30.0
    controls = [AttributeControl("walk", "happy", 90, fps, "walk-happy"),
                AttributeControl("walk", "sad", 120, fps, "walk-sad"),
                AttributeControl("run", "tired", 90, fps, "run-tired"),
                AttributeControl("kick", "happy", 60, fps, "kick-happy")]
    pairs = {m.shown: m for m in choose_mismatches(controls)}
    partner = pairs["walk-happy"].partner
    assert (partner.name, partner.frames) == ("walk-sad", 90)  # shares the action; kick-happy is too short
    assert pairs["kick-happy"].partner.name in {"walk-happy", "walk-sad", "run-tired"}
    assert pairs["walk-sad"].partner is None and "as long" in pairs["walk-sad"].reason
    checks = {m.shown: m for m in choose_attention_checks(controls)}
    assert checks["walk-happy"].partner.name == "run-tired"  # differs in both
    assert checks["walk-happy"].partner.frames == 90


def test_a_study_with_one_name_twice_or_two_frame_rates_is_refused():
    walk = preset_path("walk-straight", 20.0)
    with pytest.raises(ValueError, match="'walk-straight' names several"):
        choose_mismatches([walk, walk])
    with pytest.raises(ValueError, match=r"share a frame rate; these have \[20.0, 30.0\] fps"):
        choose_mismatches([walk, preset_path("walk-circle", 30.0)])
