"""Random, oversized, non-finite and wrongly-typed content fed to the readers an upload
reaches: the BVH reader, the motion ``.npz`` reader and the label reader. Whatever comes
in, only the project's own errors come out (BVHError, MotionFileError, a ValueError naming
the label file), never an IndexError, a KeyError, numpy's ValueError or a RecursionError.

Examples are drawn reproducibly (``derandomize``, so a failure in CI fails again at the
desk) and few enough that each test takes a few seconds.
"""

from __future__ import annotations

import io
import json
import math
import struct
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from generation.motion.bvh import BVHError, bvh_duration, read_bvh
from generation.motion.clip_files import read_labels
from generation.motion.npz import MotionFileError, load_motion_npz
from tests.test_motion_bvh import SMALL_BVH

EXAMPLES = 300
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

# Tokens that have broken parsers: non-finite and oversized numbers, numbers that are no
# numbers, keywords out of place, braces, control characters and non-ASCII text.
HOSTILE_TOKENS = ["nan", "-nan", "inf", "-inf", "1e308", "-1e308", "1e400", "1e-320", "9" * 5000, "0x10", "1_000",
                  "", "{", "}", "ROOT", "JOINT", "End", "Site", "OFFSET", "CHANNELS", "MOTION", "HIERARCHY", "Frames:",
                  "Frame", "Time:", "-1", "0", "99999999999", "2147483648", "\x00", "\x0b", "\u2028", "é", "Xrotation",
                  "Zposition", "Wrotation", "CHANNELS 0", "CHANNELS -3", "CHANNELS 99999999999999999999"]


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """One folder for every example: each overwrites the files it reads."""
    return tmp_path_factory.mktemp("fuzz")


def mutated_bvh(draw) -> str:
    """SMALL_BVH with tokens replaced, lines dropped, repeated or inserted."""
    lines = [line.split(" ") if " " in line else line.split("\t") for line in SMALL_BVH.splitlines()]
    for _ in range(draw(st.integers(1, 6))):
        action = draw(st.sampled_from(["replace", "drop", "repeat", "insert"]))
        i = draw(st.integers(0, len(lines) - 1))
        token = draw(st.one_of(st.sampled_from(HOSTILE_TOKENS),
                               st.floats(allow_nan=True, allow_infinity=True).map(repr),
                               st.integers(-(10**30), 10**30).map(str),
                               st.text(max_size=20)))
        if action == "replace":
            lines[i][draw(st.integers(0, len(lines[i]) - 1))] = token
        elif action == "drop" and len(lines) > 1:
            del lines[i]
        elif action == "repeat":
            lines.insert(i, list(lines[i]) * draw(st.integers(1, 3)))
        else:
            lines.insert(i, [token])
    return "\n".join(" ".join(line) for line in lines) + "\n"


bvh_texts = st.one_of(st.composite(mutated_bvh)(), st.text(max_size=500),
                      st.lists(st.sampled_from(HOSTILE_TOKENS + [" ", "\n", "\t"]), max_size=60).map("".join))


def read_as_bvh(path: Path) -> None:
    """Either a motion (with finite positions, its header's duration agreeing) or a
    BVHError naming the file; bvh_duration, reading the header only, refuses only what
    read_bvh refuses."""
    try:
        bvh = read_bvh(path)
    except BVHError as error:
        assert str(error).startswith(str(path))
        bvh = None
    try:
        seconds = bvh_duration(path)
    except BVHError as error:
        assert bvh is None and str(error).startswith(str(path))
    else:
        assert math.isfinite(seconds) and seconds > 0
        if bvh is not None:
            assert seconds == pytest.approx(len(bvh.values) * bvh.frame_time)
    if bvh is not None:
        assert np.isfinite(bvh.to_motion().positions).all()


@FUZZ
@given(text=bvh_texts)
def test_a_bvh_of_any_text_reads_or_is_refused_with_a_bvh_error(text, folder):
    path = folder / "clip.bvh"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    read_as_bvh(path)


@FUZZ
@given(data=st.binary(max_size=2000), prefix=st.sampled_from([b"", b"HIERARCHY\n", SMALL_BVH.encode()[:200]]))
def test_a_bvh_of_any_bytes_reads_or_is_refused_with_a_bvh_error(data, prefix, folder):
    path = folder / "clip.bvh"
    path.write_bytes(prefix + data)
    read_as_bvh(path)


# Arrays of every dtype kind an .npz can hold without pickles, of small odd shapes,
# with NaN, infinities and extremes among their values.
DTYPES = st.one_of(hnp.floating_dtypes(), hnp.integer_dtypes(), hnp.unsigned_integer_dtypes(), hnp.boolean_dtypes(),
                   hnp.complex_number_dtypes(), hnp.unicode_string_dtypes(max_len=8), hnp.byte_string_dtypes(max_len=8),
                   hnp.datetime64_dtypes(), hnp.timedelta64_dtypes())
any_array = hnp.arrays(DTYPES, hnp.array_shapes(min_dims=0, max_dims=4, min_side=0, max_side=4))


@st.composite
def motion_arrays(draw) -> dict[str, np.ndarray]:
    """A valid three-joint motion with some of its arrays replaced by anything, or left out."""
    arrays = {"positions": np.zeros((4, 3, 3)), "fps": np.float64(20.0), "names": np.array(["hips", "spine", "head"]),
              "parents": np.array([-1, 0, 1]), "offsets": np.ones((3, 3))}
    for key in draw(st.lists(st.sampled_from(sorted(arrays)), min_size=1, max_size=3, unique=True)):
        if draw(st.booleans()) and key != "positions":
            del arrays[key]
        else:
            arrays[key] = draw(any_array)
    return arrays


def read_as_npz(data: bytes) -> None:
    try:
        load_motion_npz(io.BytesIO(data), name="lab/clip.npz")
    except MotionFileError as error:
        assert str(error).startswith("lab/clip.npz: ")


@FUZZ
@given(arrays=motion_arrays())
def test_an_npz_of_any_arrays_reads_or_is_refused_naming_the_array(arrays):
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    read_as_npz(buffer.getvalue())


@FUZZ
@given(cut=st.floats(0, 1), flips=st.lists(st.tuples(st.floats(0, 1), st.integers(1, 255)), max_size=8),
       junk=st.binary(max_size=64))
def test_a_damaged_npz_reads_or_is_refused_naming_the_file(cut, flips, junk):
    buffer = io.BytesIO()
    np.savez_compressed(buffer, positions=np.zeros((4, 3, 3)), fps=np.float64(20.0), parents=np.array([-1, 0, 1]),
                        names=np.array(["hips", "spine", "head"]))
    data = bytearray(buffer.getvalue()[: max(1, int(len(buffer.getvalue()) * cut))] + junk)
    for where, mask in flips:
        data[min(int(where * len(data)), len(data) - 1)] ^= mask
    read_as_npz(bytes(data))


def npy_member(header: str, payload: bytes = b"") -> bytes:
    """An .npy file of version 1.0 with ``header`` as its dictionary, whatever it says."""
    text = header.encode("latin-1") + b" " * ((64 - (len(header) + 11) % 64) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text + payload


HOSTILE_HEADERS = {
    "a shape of 10^12 frames": "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000, 3, 3), }",
    "a shape past any memory": "{'descr': '<f8', 'fortran_order': False, 'shape': (4611686018427387904, 4), }",
    "a negative shape": "{'descr': '<f8', 'fortran_order': False, 'shape': (-1, 3, 3), }",
    "pickled objects": "{'descr': '|O', 'fortran_order': False, 'shape': (3,), }",
    "no dtype": "{'fortran_order': False, 'shape': (3,), }",
    "a dtype that is no dtype": "{'descr': 'not-a-dtype', 'fortran_order': False, 'shape': (3,), }",
    "Python code": "__import__('os').system('true')",
    "nested a thousand deep": "{'descr': " + "[" * 1000 + "]" * 1000 + ", 'fortran_order': False, 'shape': (3,), }",
}


@pytest.mark.parametrize("member", ["positions", "parents", "names", "fps"])
@pytest.mark.parametrize("header", HOSTILE_HEADERS.values(), ids=HOSTILE_HEADERS.keys())
def test_hostile_npy_headers_inside_an_npz_are_refused_naming_the_array(header, member):
    buffer = io.BytesIO()
    np.savez(buffer, positions=np.zeros((4, 3, 3)), fps=np.float64(20.0), parents=np.array([-1, 0, 1]),
             names=np.array(["hips", "spine", "head"]))
    with zipfile.ZipFile(buffer) as source:
        members = {name: source.read(name) for name in source.namelist()}
    members[f"{member}.npy"] = npy_member(header, b"\x00" * 72)
    hostile = io.BytesIO()
    with zipfile.ZipFile(hostile, "w") as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    with pytest.raises(MotionFileError, match=f"^lab/clip.npz: {member}: cannot be read"):
        load_motion_npz(io.BytesIO(hostile.getvalue()), name="lab/clip.npz")


# JSON values of every kind, nested a little, oversized and non-finite among them.
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-(10**40), 10**40), st.floats(allow_nan=True, allow_infinity=True),
              st.text(max_size=30), st.sampled_from(HOSTILE_TOKENS)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=10)
side_files = st.one_of(
    st.fixed_dictionaries({}, optional={"content": json_values, "style": json_values}).map(json.dumps),
    json_values.map(json.dumps),
    st.sampled_from(["[" * 100_000, '{"content": ' + "9" * 5000 + "}", '{"content": 1e400}', '{"content": NaN}',
                     '{"content": "walk", "content": 1}', "\ufeff{}"]),
    st.text(max_size=200))
label_lists = st.one_of(st.none(), st.lists(st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=12),
                                            max_size=6).map("\n".join),
                        st.binary(max_size=64))


@FUZZ
@given(side=side_files, names=label_lists, raw=st.booleans())
def test_a_label_file_of_any_content_reads_or_is_refused_naming_a_file(side, names, raw, folder):
    bvh = folder / "clip.bvh"
    bvh.write_text(SMALL_BVH)
    label_list = folder / "content_label.txt"
    label_list.unlink(missing_ok=True)
    if isinstance(names, bytes):
        label_list.write_bytes(names)
    elif names is not None:
        label_list.write_text(names, encoding="utf-8")
    side_file = bvh.with_suffix(".json")
    side_file.write_bytes(side.encode("utf-8", "surrogatepass") if not raw else side.encode("utf-16"))
    try:
        labels = read_labels(bvh)
    except ValueError as error:
        assert str(error).startswith((str(side_file), str(label_list))), error
    else:
        assert all(label is None or isinstance(label, str) for label in labels)

