"""`wallbatch plot -o`: a directory, a name without extension or an extension matplotlib cannot
write is an error naming `-o` (matplotlib wrote NAME.png for `-o NAME` and DIR.png for `-o DIR`,
while the command said `wrote NAME`; an unknown extension failed late without naming `-o`)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from wallbatch.cli import app

SCENE = """\
box: {lo: [0, 0, 0], hi: [10, 10, 12], boundary: [p, p, f]}
atoms:
  - group: gas
    create: {random: {count: 10, region: slab}}
    mass: 1.0
    velocity: {temperature: 1.0}
regions:
  slab: {style: block, lo: [0, 0, 3], hi: [10, 10, 9], units: box}
walls:
  w: {style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}
run: {steps: 10, thermo: 5}
"""


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    """A one-case results file."""
    folder = tmp_path_factory.mktemp("plot")
    (folder / "s.yaml").write_text(SCENE)
    out = folder / "s.nc"
    got = CliRunner().invoke(app, ["run", str(folder / "s.yaml"), "-o", str(out)])
    assert got.exit_code == 0, got.output
    return out


def plot(results: Path, output: Path):
    """Run `wallbatch plot RESULTS temp -o OUTPUT`."""
    return CliRunner().invoke(app, ["plot", str(results), "temp", "-o", str(output)])


def test_directory(results: Path, tmp_path: Path) -> None:
    got = plot(results, tmp_path)
    assert got.exit_code == 2
    assert got.output.strip() == f"error: -o {tmp_path} is a directory: give a file name, e.g. {tmp_path / 'temp.png'}"
    assert not tmp_path.with_suffix(".png").exists()


def test_no_extension(results: Path, tmp_path: Path) -> None:
    got = plot(results, tmp_path / "fig")
    assert got.exit_code == 2
    assert got.output.strip() == (f"error: -o {tmp_path / 'fig'}: give the image format as the file's extension, "
                                  f"e.g. {tmp_path / 'fig'}.png")
    assert list(tmp_path.iterdir()) == []


def test_unknown_extension(results: Path, tmp_path: Path) -> None:
    got = plot(results, tmp_path / "fig.txt")
    assert got.exit_code == 2
    assert got.output.strip().startswith(f"error: -o {tmp_path / 'fig.txt'}: .txt is not an image format matplotlib "
                                         "writes: use one of ")
    assert "png" in got.output


def test_png_written(results: Path, tmp_path: Path) -> None:
    got = plot(results, tmp_path / "fig.PNG")
    assert got.exit_code == 0, got.output
    assert (tmp_path / "fig.PNG").read_bytes()[:4] == b"\x89PNG"
