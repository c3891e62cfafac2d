"""The parts (batch/runner.py save_part, read_part, part_bytes, parse_part): every array back bit
for bit whatever its dtype, shape or byte order; a truncated, foreign or inconsistent file is
an error (read_part: "damaged", recomputed); and no cyclic garbage, so the peak memory of a run
reading thousands of parts back does not follow the garbage collector's timing."""

from __future__ import annotations

import os

import numpy as np
import pytest
from factories import cyclic_garbage

from wallbatch.batch.runner import PART_SUFFIX, parse_part, part_bytes, read_part, save_part
from wallbatch.engine.engine import CaseResult

ARRAYS = {
    "pe": np.linspace(-3.0, 1.0, 21),
    "wall_force": np.arange(24.0).reshape(4, 3, 2) * -0.5,
    "fortran": np.asfortranarray(np.arange(12.0).reshape(3, 4)),
    "steps": np.arange(7, dtype=np.int64),
    "small": np.arange(5, dtype=np.int32),
    "lost": np.array([True, False, True]),
    "names": np.array(["zlo", "zhi", "xlo_wall"]),
    "empty": np.zeros((0, 3)),
    "scalar": np.float64(0.125),
    "big_endian": np.arange(4, dtype=">f8"),
    "nan_inf": np.array([np.nan, -np.inf, -0.0]),
}


def test_a_part_gives_back_every_array_bit_for_bit(tmp_path):
    res = CaseResult("failed", "walls.w zlo: atom ID 3 at distance -0.1 \u2264 0", 0.25, dict(ARRAYS))
    save_part(tmp_path, "key", res)
    assert sorted(os.listdir(tmp_path)) == [f"key{PART_SUFFIX}"]  # no temporary left
    back, why = read_part(tmp_path, "key")
    assert why == "" and back is not None
    assert (back.status, back.error, back.seconds) == (res.status, res.error, 0.25)
    assert sorted(back.data) == sorted(ARRAYS)
    for name, arr in ARRAYS.items():
        got = back.data[name]
        ref = np.ascontiguousarray(arr)
        assert got.dtype == ref.dtype and got.shape == ref.shape, name
        assert got.tobytes() == ref.tobytes(), name
        assert got.flags.writeable and got.flags.c_contiguous, name


def test_truncated_foreign_and_inconsistent_files_are_errors():
    raw = part_bytes("key", CaseResult("ok", "", 0.5, {"pe": np.arange(10.0)}), "0" * 64)
    head, data = parse_part(raw)
    assert head["case_key"] == "key" and data["pe"].tolist() == list(range(10))
    for bad in (raw[:-8], raw[:20], b"", b"PK\x03\x04" + raw[4:]):  # short data or header; empty; a zip
        with pytest.raises(ValueError):
            parse_part(bad)
    with pytest.raises(TypeError, match="Python objects"):
        part_bytes("key", CaseResult("ok", "", 0.0, {"o": np.array([None])}), "")


def test_read_part_reports_what_is_wrong(tmp_path):
    res = CaseResult("ok", "", 0.5, {"pe": np.arange(10.0)})
    save_part(tmp_path, "a", res)
    path = tmp_path / f"a{PART_SUFFIX}"
    good = path.read_bytes()
    assert read_part(tmp_path, "b") == (None, "")  # absent
    path.write_bytes(good[:-1])
    assert read_part(tmp_path, "a") == (None, "damaged (ValueError)")
    flipped = bytearray(good)
    flipped[-3] ^= 0x10  # a bit of the data: the file still parses
    path.write_bytes(bytes(flipped))
    assert read_part(tmp_path, "a") == (None, "damaged (content hash differs)")
    os.replace(tmp_path / f"a{PART_SUFFIX}", tmp_path / f"c{PART_SUFFIX}")
    save_part(tmp_path, "a", res)
    os.replace(tmp_path / f"a{PART_SUFFIX}", tmp_path / f"d{PART_SUFFIX}")
    assert read_part(tmp_path, "d") == (None, "belongs to another case")


def test_a_part_of_the_previous_format_is_not_read(tmp_path):
    """Parts of wallbatch versions before PART_FORMAT 3 were .npz archives: reported and
    recomputed (and a run without --resume still refuses while they are there: test_resume)."""
    np.savez(tmp_path / "a.npz", status=np.str_("ok"))
    assert read_part(tmp_path, "a") == (None, "written by an older wallbatch")
    (tmp_path / f"a{PART_SUFFIX}").write_bytes((tmp_path / "a.npz").read_bytes())
    assert read_part(tmp_path, "a") == (None, "damaged (ValueError)")


@pytest.mark.slow
def test_reading_parts_leaves_no_cyclic_garbage(tmp_path):
    res = CaseResult("ok", "", 0.25, dict(ARRAYS))
    save_part(tmp_path, "key", res)
    with cyclic_garbage() as left:
        for _ in range(20):
            back, why = read_part(tmp_path, "key")
            assert back is not None, why
    assert left["found"] == 0, f"{left['found']} cyclic objects left by 20 reads: {left['kinds']}"
    for name, arr in res.data.items():
        assert back.data[name].tobytes() == np.ascontiguousarray(arr).tobytes(), name
