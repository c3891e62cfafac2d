"""`wallbatch check` refuses a region that atoms are created in (create.random.region,
create.lattice.region) when it has no room in the box: it created no atom, and the case failed
to build with 'placed only 0 of N atoms ...: lower count or overlap', which named neither the
region nor the box. A region lying partly outside the box is fine (the atoms go in the part
inside, as LAMMPS clips)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from wallbatch.cli import app
from wallbatch.geometry.regions import RegionGeom

SCENE = """\
box: {{lo: [0, 0, 0], hi: [10, 10, 12], boundary: [p, p, f]}}
lattice: {{style: sc, scale: 2.0}}
atoms:
  - group: gas
    create: {{{create}: {{{count}region: slab}}}}
    mass: 1.0
regions:
  slab: {region}
walls:
  w: {{style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}}
run: {{steps: 10, thermo: 5}}
"""


def check(tmp_path: Path, region: str, create: str = "random"):
    config = tmp_path / "s.yaml"
    count = "count: 10, " if create == "random" else ""
    config.write_text(SCENE.format(region=region, create=create, count=count))
    return config, CliRunner().invoke(app, ["check", str(config)])


@pytest.mark.parametrize("region, create", [
    ("{style: block, lo: [0, 0, 20], hi: [10, 10, 30], units: box}", "random"),
    ("{style: block, lo: [-5, 2, 2], hi: [-1, 8, 8], units: box}", "lattice"),
    ("{style: sphere, center: [15, 15, 6], radius: 7, units: box}", "random"),  # 7.07 from the box edge
    ("{style: cylinder, axis: z, center: [5, 5], radius: 2, lo: 13, hi: 20, units: box}", "random"),
    # lattice units (the default): sc at reduced density 2 has the spacing 0.5^(1/3), z 15.9..23.8
    ("{style: block, lo: [0, 0, 20], hi: [5, 5, 30]}", "random"),
])
def test_a_region_wholly_outside_the_box_is_refused_at_the_region(tmp_path, region, create):
    config, got = check(tmp_path, region, create)
    assert got.exit_code == 2, got.output
    lines = got.output.strip().splitlines()
    assert lines[0] == "error: invalid config"
    assert lines[1].startswith(f"{config}:8:9: regions.slab: region slab lies wholly outside the box (box lo [0, 0, 0] "
                               f"hi [10, 10, 12]")
    assert ("the region's numbers are lattice units, times the lattice spacing 0.793701" in lines[1]) == (
        "units: box" not in region)
    assert lines[1].endswith(f"so atoms.0.create.{create} (group gas) would create no atom: move or resize the region "
                             f"so that part of it is in the box, or enlarge the box")


def test_a_side_out_region_holding_the_whole_box_is_refused(tmp_path):
    config, got = check(tmp_path, "{style: sphere, side: out, center: [5, 5, 6], radius: 20, units: box}")
    assert got.exit_code == 2, got.output
    assert (f"{config}:8:9: regions.slab: region slab (side: out) leaves nothing of the box: its sphere holds the "
            f"whole box") in got.output
    assert "shrink or move the sphere, or use side: in" in got.output


@pytest.mark.parametrize("region, create", [
    ("{style: block, lo: [0, 0, 8], hi: [10, 10, 30], units: box}", "random"),  # partly outside: clipped
    ("{style: sphere, center: [12, 5, 6], radius: 3, units: box}", "random"),
    ("{style: cylinder, axis: z, center: [5, 5], radius: 2, lo: -10, hi: 3, units: box}", "lattice"),
    ("{style: sphere, side: out, center: [5, 5, 6], radius: 6, units: box}", "random"),  # the corners stay
])
def test_a_region_partly_outside_the_box_passes(tmp_path, region, create):
    _, got = check(tmp_path, region, create)
    assert got.exit_code == 0, got.output
    assert "case(s) cannot be built" not in got.output


def test_misses_box_geometry():
    box = ([0, 0, 0], [10, 10, 12])
    assert RegionGeom("block", lo=(10, 0, 0), hi=(20, 10, 12)).misses_box(*box) is False  # touching a face
    assert RegionGeom("block", lo=(10.5, 0, 0), hi=(20, 10, 12)).misses_box(*box) is True
    assert RegionGeom("sphere", center=(13, 5, 6), radius=3.0).misses_box(*box) is False
    assert RegionGeom("sphere", center=(13.01, 5, 6), radius=3.0).misses_box(*box) is True
    assert RegionGeom("cylinder", center=(5, 5), radius=1.0, lo=12.0, hi=20.0, axis=2).misses_box(*box) is False
    assert RegionGeom("cylinder", center=(12, 12), radius=2.0, lo=0.0, hi=12.0, axis=2).misses_box(*box) is True
    # a 2-D run: the plane z = 0
    assert RegionGeom("block", lo=(0, 0, 0.5), hi=(10, 10, 1)).misses_box([0, 0, 0], [10, 10, 0]) is True
    assert RegionGeom("block", side="out", lo=(-1, -1, -1), hi=(11, 11, 13)).misses_box(*box) is True
    assert RegionGeom("block", side="out", lo=(-1, -1, -1), hi=(11, 11, 11)).misses_box(*box) is False


WALL_SCENE = """\
box: {{lo: [0, 0, 0], hi: [10, 10, 12], boundary: [p, p, f]}}
atoms:
  - group: gas
    create: {{random: {{count: 10}}}}
    mass: 1.0
regions:
  pore: {region}
walls:
  w: {{style: lj93, units: box, zlo: [EDGE, 1.0, 1.0, 2.5], zhi: [EDGE, 1.0, 1.0, 2.5]}}
  cav: {{style: region, region: pore, potential: lj93, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}}
run: {{steps: 10, thermo: 5}}
"""


@pytest.mark.parametrize("region, refused", [
    ("{style: sphere, center: [25, 5, 6], radius: 4, units: box}", "lies wholly outside the box"),
    ("{style: sphere, side: out, center: [5, 5, 6], radius: 20, units: box}", "(side: out) leaves nothing of"),
    ("{style: sphere, center: [5, 5, 6], radius: 20, units: box}", None),  # holds the box: fine
    ("{style: cylinder, axis: z, center: [12, 5], radius: 3, lo: -1, hi: 13, units: box}", None),  # partly in
])
def test_a_wall_region_with_no_room_in_the_box_is_refused_at_the_region(tmp_path, region, refused):
    """A wall/region whose region has no room in the box would find every atom outside its surface
    (LAMMPS stops at setup: Particle outside surface of region used in fix wall/region); `check`
    says so at the region, naming the wall. A region partly in the box passes."""
    config = tmp_path / "s.yaml"
    config.write_text(WALL_SCENE.format(region=region))
    got = CliRunner().invoke(app, ["check", str(config)])
    if refused is None:
        assert got.exit_code == 0, got.output
        return
    assert got.exit_code == 2, got.output
    assert f"{config}:7:9: regions.pore: region pore {refused}" in got.output, got.output
    assert ("so walls.cav (wall/region) would find every atom outside its surface (LAMMPS stops: Particle "
            "outside surface of region used in fix wall/region)") in got.output
