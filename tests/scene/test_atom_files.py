"""Errors in atom files (`atoms: [{create: {file: ...}}]`) name the atom file and its line (or
array and row) and the config field and file:line that named it (issue 14)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from wallbatch.config.models import load_config
from wallbatch.scene.build import build_case
from wallbatch.scene.case import CaseError

CONFIG = """\
units: lj
seed: 1
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {file: %s}
    mass: 1.0
run: {steps: 10, thermo: 5}
"""

DATA = """\
LAMMPS data file

3 atoms
1 atom types

0 10 xlo xhi
0 10 ylo yhi
0 10 zlo zhi

Atoms # atomic

1 1 1.0 1.0 1.0
2 1 2.0 2.0 %s
3 1 3.0 3.0 3.0
"""


def build_error(tmp: Path, name: str) -> str:
    cfg = tmp / "scene.yaml"
    cfg.write_text(CONFIG % name)
    with pytest.raises(CaseError) as err:
        build_case(load_config(cfg))
    return str(err.value)


def test_good_files_build(tmp_path):
    (tmp_path / "ok.data").write_text(DATA % "2.0")
    cfg = tmp_path / "scene.yaml"
    cfg.write_text(CONFIG % "ok.data")
    assert build_case(load_config(cfg)).natoms == 3
    np.savez(tmp_path / "ok.npz", x=np.full((4, 3), 5.0), v=np.zeros((4, 3)))
    cfg.write_text(CONFIG % "ok.npz")
    assert build_case(load_config(cfg)).natoms == 4


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_data_file_non_finite_names_file_line_and_field(tmp_path, value):
    (tmp_path / "bad.data").write_text(DATA % value)
    msg = build_error(tmp_path, "bad.data")
    assert re.match(rf"{re.escape(str(tmp_path / 'scene.yaml'))}:6:\d+: atoms\.0\.create\.file: ", msg), msg
    assert f"{tmp_path / 'bad.data'}:13: a non-finite value (inf or nan) in the Atoms line '2 1 2.0 2.0 {value}'" in msg


def test_data_file_short_line_and_missing_file(tmp_path):
    (tmp_path / "short.data").write_text(DATA % "")
    msg = build_error(tmp_path, "short.data")
    assert "scene.yaml:6:" in msg and "atoms.0.create.file" in msg
    assert f"{tmp_path / 'short.data'}:13: a Atoms line of atom_style atomic has" in msg and "got 4" in msg
    msg = build_error(tmp_path, "gone.data")
    assert "scene.yaml:6:" in msg and "atoms.0.create.file" in msg and "gone.data" in msg


def test_data_file_wrong_count(tmp_path):
    (tmp_path / "count.data").write_text((DATA % "2.0").replace("3 atoms", "4 atoms"))
    msg = build_error(tmp_path, "count.data")
    assert "scene.yaml:6:" in msg and f"{tmp_path / 'count.data'}:" in msg and "header says" in msg


@pytest.mark.slow
@pytest.mark.parametrize("arrays, words", [
    ({"x": np.array([[1.0, 1, 1], [2, np.nan, 2]])}, "array x has a non-finite value (inf or nan) at row 1 (atom 2"),
    ({"x": np.ones((3, 3)), "v": np.array([[0.0, 0, 0], [np.inf, 0, 0], [0, 0, 0]])},
     "array v has a non-finite value (inf or nan) at row 1"),
    ({"x": np.ones((3, 3)), "v": np.zeros((2, 3))}, "array v has shape (2, 3), expected (3, 3)"),
    ({"x": np.ones((3, 3)), "radius": np.zeros(4)}, "array radius has shape (4,), expected (3,)"),
    ({"x": np.ones((3, 2))}, "needs an array x of shape (N, 3), got shape (3, 2)"),
    ({"pos": np.ones((3, 3))}, "needs an array x of shape (N, 3), got arrays ['pos']"),
])
def test_npz_errors_name_file_array_and_field(tmp_path, arrays, words):
    np.savez(tmp_path / "atoms.npz", **arrays)
    msg = build_error(tmp_path, "atoms.npz")
    assert "scene.yaml:6:" in msg and "atoms.0.create.file" in msg and str(tmp_path / "atoms.npz") in msg, msg
    assert words in msg, msg


def test_npz_damaged(tmp_path):
    np.savez(tmp_path / "atoms.npz", x=np.ones((3, 3)))
    data = (tmp_path / "atoms.npz").read_bytes()
    (tmp_path / "atoms.npz").write_bytes(data[: len(data) // 2])
    msg = build_error(tmp_path, "atoms.npz")
    assert "scene.yaml:6:" in msg and "cannot read" in msg and "as a NumPy .npz archive" in msg, msg
