"""Mismatched controls for appropriateness studies: which other control's clip a page
shows beside a system's clip for the shown control.

An appropriateness page shows one system twice: its clip for the control the page shows
(a path drawn on the floor, or a label in words) and its clip for another control, the
*partner*, and asks which fits the shown control better. The partner must differ in
what the control asks for and in nothing else a participant could answer by, so the
answer is about following. Every system gets the same partner for a control, so their
scores compare like with like. The rule, for each shown control:

Paths
  1. Same length: a partner lasts at least as many frames, and is cut to the shown
     control's (``partner.n_frames == shown.n_frames``).
  2. Comparable speed: its mean speed over the floor is within ``SPEED_BAND`` (25 %) of
     the shown control's, or within ``SPEED_FLOOR`` (15 cm/s) for slow ones: pace does
     not give the mismatched clip away.
  3. Different shape: stretched to the shown path's length, the partner's path departs
     from it by at least ``SHAPE_GAP`` (30 %) of that length somewhere
     (``shape_gap``: the largest distance between the two paths at equal shares of
     their lengths, pace left out). Paths that travel under ``STILL_CM`` have no shape
     and differ when they turn ``TURN_BAND`` (45°) apart.
  4. Comparable, not glaring: among those, a partner whose net turning is within
     ``TURN_BAND`` of the shown one's in amount and that departs by less than
     ``ATTENTION_GAP`` (60 %) is drawn at random (seeded); where there is none, the one
     closest in turning, preferring those departing by less than ``ATTENTION_GAP``.
Labels
  A different action and style pair, as long; one that shares the action or the style
  is drawn first (at random, seeded), else any other pair.
Natural motion
  A control cut from a natural take (named in ``takes``) is only paired with other
  takes, so NAT's mismatched clip is another take of comparable speed and turning.

Attention checks (``choose_attention_checks``) pair a control with an obviously wrong
partner, for NAT pages that an attentive participant cannot get wrong: the path departing
most from the shown one (at least ``ATTENTION_GAP``, at any speed; for a path that
stands, the one travelling furthest), or labels that differ in both action and style.

A draw ranks the candidates by a number hashed from the seed and the two controls'
names and takes the first: the same seed gives the same pairs whatever the order of the
controls, and removing a control changes only the pairs it was in.
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

from .control import AttributeControl, Control, PathControl

SPEED_BAND = 0.25  # of the shown control's mean speed
SPEED_FLOOR = 15.0  # cm/s: the band of slow controls, where a quarter is nothing
SHAPE_GAP = 0.30  # of the shown path's length: the least departure of a mismatched path
ATTENTION_GAP = 0.60  # of its length: beyond this a path is obviously another
TURN_BAND = 45.0  # degrees of net turning
STILL_CM = 50.0  # a path travelling less has no shape
SHAPE_POINTS = 64  # points along a path at equal shares of its length


@dataclass(frozen=True)
class PathSummary:
    """What the rule reads from a path control."""

    frames: int
    speed: float  # mean speed over the floor, cm/s
    turning: float  # net turning, degrees, left positive
    length: float  # distance travelled, cm
    shape: np.ndarray  # (SHAPE_POINTS, 2): the path at equal shares of its length, divided by it


def path_summary(control: PathControl) -> PathSummary:
    v = control.velocities
    xz = control.path().xz
    steps = np.linalg.norm(np.diff(xz, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    length = float(along[-1])
    shares = np.linspace(0.0, length, SHAPE_POINTS)
    shape = np.column_stack([np.interp(shares, along, xz[:, 0]), np.interp(shares, along, xz[:, 1])])
    return PathSummary(frames=control.n_frames, speed=float(np.hypot(v[:, 0], v[:, 1]).mean()),
                       turning=float(np.degrees(v[1:, 2].sum() / control.fps)), length=length,
                       shape=shape / max(length, 1e-9))


def shape_gap(shown: PathSummary, partner: PathSummary) -> float:
    """How far the partner's path, stretched to the shown path's length, departs from it at
    most, as a share of that length: 0 for one shape at any pace, about 0.7 for a right
    angle, 2 for the opposite direction."""
    return float(np.linalg.norm(shown.shape - partner.shape, axis=1).max())


@dataclass(frozen=True)
class Mismatch:
    """A shown control's partner (cut to its length), or None and the reason why there is none."""

    shown: str
    partner: Control | None
    reason: str  # how the partner was chosen, or why none was
    speed_ratio: float | None = None  # the partner's mean speed over the shown one's
    turning_difference: float | None = None  # degrees, in amount of net turning
    shape_gap: float | None = None  # see ``shape_gap``

    def to_dict(self) -> dict:
        return {"shown": self.shown, "partner": None if self.partner is None else self.partner.name,
                "reason": self.reason, "speed_ratio": self.speed_ratio,
                "turning_difference": self.turning_difference, "shape_gap": self.shape_gap}


def choose_mismatches(controls: Sequence[Control], seed: int = 0, takes: Collection[str] = ()) -> list[Mismatch]:
    """Each control's mismatched partner among the others, by the rule above, in order."""
    _check_study(controls)
    return [_path_partner(shown, _candidates(shown, controls, takes), seed)
            if isinstance(shown, PathControl) else
            _label_partner(shown, _candidates(shown, controls, takes), seed, attention=False)
            for shown in controls]


def choose_attention_checks(controls: Sequence[Control], seed: int = 0,
                            takes: Collection[str] = ()) -> list[Mismatch]:
    """Each control's obviously wrong partner (see the module's docstring), in order."""
    _check_study(controls)
    return [_path_attention(shown, _candidates(shown, controls, takes))
            if isinstance(shown, PathControl) else
            _label_partner(shown, _candidates(shown, controls, takes), seed, attention=True)
            for shown in controls]


def _check_study(controls: Sequence[Control]) -> None:
    names = [c.name for c in controls]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"controls are told apart by name, and {', '.join(map(repr, twice))} names several")
    rates = {c.fps for c in controls}
    if len(rates) > 1:
        raise ValueError(f"the controls of one study share a frame rate; these have {sorted(rates)} fps")


def _candidates(shown: Control, controls: Sequence[Control], takes: Collection[str]) -> list[Control]:
    """The other controls of the same kind, as long or longer (cut to the shown one's
    length), only takes for a take; sorted by name so that the order given does not matter."""
    found = [_cut(c, shown.n_frames) for c in controls
             if type(c) is type(shown) and c.name != shown.name and c.n_frames >= shown.n_frames
             and (shown.name not in takes or c.name in takes)]
    return sorted(found, key=lambda c: c.name)


def _cut(control: Control, frames: int) -> Control:
    if isinstance(control, PathControl):
        return PathControl(control.velocities[:frames], control.fps, control.name, control.lead_in)
    return AttributeControl(control.action, control.style, frames, control.fps, control.name)


def _draw(seed: int, shown: Control, pool: Sequence[Control]) -> int:
    """The index of the drawn one of ``pool``: the least number hashed from the seed and
    both names, so a draw depends on no other control."""
    def rank(partner: Control) -> bytes:
        return hashlib.sha256(f"{seed}\0{shown.name}\0{partner.name}".encode()).digest()

    return min(range(len(pool)), key=lambda i: rank(pool[i]))


def _measured(shown: PathControl, a: PathSummary, partner: PathControl, b: PathSummary, reason: str) -> Mismatch:
    return Mismatch(shown.name, partner, reason, speed_ratio=b.speed / a.speed if a.speed > 0 else None,
                    turning_difference=abs(abs(b.turning) - abs(a.turning)),
                    shape_gap=None if min(a.length, b.length) < STILL_CM else shape_gap(a, b))


def _path_partner(shown: PathControl, candidates: list[Control], seed: int) -> Mismatch:
    a = path_summary(shown)
    if not candidates:
        return Mismatch(shown.name, None, "no other control of the study is as long")
    band = max(SPEED_BAND * a.speed, SPEED_FLOOR)
    pace = [(c, b) for c, b in zip(candidates, map(path_summary, candidates)) if abs(b.speed - a.speed) <= band]
    usable = [(c, b) for c, b in pace if _shapes_differ(a, b)]
    if not usable:
        why = "is within the speed band" if not pace else "within the speed band differs in shape"
        return Mismatch(shown.name, None, f"no other control of the study as long {why}")
    comparable = [(c, b) for c, b in usable if _comparable(a, b)]
    if comparable:
        c, b = comparable[_draw(seed, shown, [c for c, _ in comparable])]
        return _measured(shown, a, c, b, "drawn among the controls within every band")
    # Not glaring before close in turning: a regular page should not look like an attention check.
    c, b = min(usable, key=lambda cb: (_glaring(a, cb[1]), abs(abs(cb[1].turning) - abs(a.turning))))
    return _measured(shown, a, c, b, "closest in turning: no control within every band")


def _shapes_differ(a: PathSummary, b: PathSummary) -> bool:
    if min(a.length, b.length) < STILL_CM:
        return abs(a.turning - b.turning) >= TURN_BAND
    return shape_gap(a, b) >= SHAPE_GAP


def _comparable(a: PathSummary, b: PathSummary) -> bool:
    return abs(abs(a.turning) - abs(b.turning)) <= TURN_BAND and not _glaring(a, b)


def _glaring(a: PathSummary, b: PathSummary) -> bool:
    """Whether ``b`` departs from ``a`` as an attention check's partner does."""
    return min(a.length, b.length) >= STILL_CM and shape_gap(a, b) >= ATTENTION_GAP


def _path_attention(shown: PathControl, candidates: list[Control]) -> Mismatch:
    a = path_summary(shown)
    scored = list(zip(candidates, map(path_summary, candidates)))
    if a.length < STILL_CM:  # a path that stands: a figure walking away is obviously wrong
        far = [(c, b) for c, b in scored if b.length >= 2 * STILL_CM]
        if not far:
            return Mismatch(shown.name, None, f"stands, and no other control as long travels {2 * STILL_CM:g} cm")
        c, b = max(far, key=lambda cb: cb[1].length)
        return _measured(shown, a, c, b, "travels furthest from a path that stands")
    moving = [(c, b, shape_gap(a, b)) for c, b in scored if b.length >= STILL_CM]
    glaring = [item for item in moving if item[2] >= ATTENTION_GAP]
    if not glaring:
        return Mismatch(shown.name, None, f"no other control as long departs by {ATTENTION_GAP:.0%} of its length")
    c, b, _ = max(glaring, key=lambda item: item[2])
    return _measured(shown, a, c, b, "departs most from the shown path")


def _label_partner(shown: AttributeControl, candidates: list[Control], seed: int, attention: bool) -> Mismatch:
    other = [c for c in candidates if (c.action, c.style) != (shown.action, shown.style)]
    both = [c for c in other if c.action != shown.action and c.style != shown.style]
    if attention:
        pool, reason = both, "differs in action and style"
    else:
        one = [c for c in other if c.action == shown.action or c.style == shown.style]
        pool, reason = (one, "shares the action or the style") if one else (other, "another label pair")
    if not pool:
        wanted = "differing in action and style" if attention else "with other labels"
        return Mismatch(shown.name, None, f"no other control as long {wanted}")
    return Mismatch(shown.name, pool[_draw(seed, shown, pool)], f"drawn at random: {reason}")
