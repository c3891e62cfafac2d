"""Reading the parts back (batch/runner.py read_npz, read_part): the arrays np.load would give, bit
for bit, and no cyclic garbage, so the peak memory of a run reading thousands of parts does not
follow the garbage collector's timing (np.load parses each array's header with
ast.literal_eval, whose nested functions are reference cycles: ~11 objects per array)."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest
from factories import cyclic_garbage

from wallbatch.batch.runner import read_npz, read_part, save_part
from wallbatch.engine.engine import CaseResult

ARRAYS = {
    "status": np.str_("ok"),
    "seconds": np.float64(0.125),
    "pe": np.linspace(-3.0, 1.0, 21),
    "wall_force": np.arange(24.0).reshape(4, 3, 2) * -0.5,
    "fortran": np.asfortranarray(np.arange(12.0).reshape(3, 4)),
    "steps": np.arange(7, dtype=np.int64),
    "small": np.arange(5, dtype=np.int32),
    "lost": np.array([True, False, True]),
    "names": np.array(["zlo", "zhi", "xlo_wall"]),
    "empty": np.zeros((0, 3)),
    "big_endian": np.arange(4, dtype=">f8"),
}


def test_read_npz_gives_np_loads_arrays_bit_for_bit(tmp_path):
    path = tmp_path / "a.npz"
    np.savez(path, **ARRAYS)
    ours = read_npz(path)
    with np.load(path, allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
    assert sorted(ours) == sorted(ref) == sorted(ARRAYS)
    for name, arr in ref.items():
        got = ours[name]
        assert got.dtype == arr.dtype and got.shape == arr.shape, name
        assert got.tobytes(order="A") == arr.tobytes(order="A"), name
        assert got.flags.f_contiguous == arr.flags.f_contiguous and got.flags.writeable, name
    assert ours["fortran"].flags.f_contiguous and not ours["fortran"].flags.c_contiguous


def test_a_header_in_another_form_is_read_by_np_load(tmp_path):
    """An archive not written the way np.savez writes it here (keys in another order): np.load's
    reading, same values."""
    path = tmp_path / "b.npz"
    arr = np.array([1.5, -2.0, 3.25])
    header = "{'shape': (3,), 'fortran_order': False, 'descr': '<f8'}"
    header += " " * (118 - len(header)) + "\n"
    body = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode() + arr.tobytes()
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("x.npy", body)
    assert read_npz(path)["x"].tolist() == arr.tolist()


def test_a_truncated_array_is_an_error(tmp_path):
    path = tmp_path / "c.npz"
    np.savez(path, x=np.arange(10.0))
    raw = zipfile.ZipFile(path).read("x.npy")
    with zipfile.ZipFile(path, "w") as zf:  # a valid archive whose array lacks its last 8 bytes
        zf.writestr("x.npy", raw[:-8])
    with pytest.raises(ValueError):
        read_npz(path)


@pytest.mark.slow
def test_reading_parts_leaves_no_cyclic_garbage(tmp_path):
    res = CaseResult("ok", "", 0.25, {k: v for k, v in ARRAYS.items() if k not in ("status", "seconds")})
    save_part(tmp_path, "key", res)
    with cyclic_garbage() as left:
        for _ in range(20):
            back, why = read_part(tmp_path, "key")
            assert back is not None, why
    assert left["found"] == 0, f"{left['found']} cyclic objects left by 20 reads: {left['kinds']}"
    for name, arr in res.data.items():
        assert back.data[name].tobytes() == np.ascontiguousarray(arr).tobytes(), name
    assert (back.status, back.error, back.seconds) == ("ok", "", 0.25)


@pytest.mark.slow
def test_np_load_would_leave_cyclic_garbage(tmp_path):
    """What the test above guards against, shown on np.load itself (if a NumPy stops making these
    cycles, read_npz is no longer needed)."""
    path = tmp_path / "d.npz"
    np.savez(path, x=np.arange(3.0), y=np.arange(2.0))
    with cyclic_garbage(save=False) as left:
        for _ in range(5):
            with np.load(path) as z:
                _ = z["x"], z["y"]
    found = left["found"]
    if found == 0:
        pytest.skip("this NumPy's np.load leaves no cyclic garbage")
    assert found >= 10
