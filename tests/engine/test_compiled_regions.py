"""wall/region in the compiled path (wallbatch.engine.compiled) against the NumPy engine.

Each scene runs with WALLBATCH_NUMBA=0 and =1 (tests/engine/test_compiled.py's `check`): every sampled output
of every case agrees to 1e-14 relative, with the same status and failure message, and the test
asserts that chunks really ran compiled (or, for scenes the kernel must refuse, that none did).
"""

from __future__ import annotations

import numpy as np
import pytest

from test_compiled import STYLE_PARAMS, check, gas

from wallbatch.config.models import config_from_dict
from wallbatch.engine import compiled as fast
from wallbatch.engine.engine import Engine
from wallbatch.scene.build import build_case

pytestmark = pytest.mark.skipif(fast.njit is None, reason="numba not importable")

L = 10.0  # box edge


def region_gas(region: dict, walls: dict, *, n=60, steps=400, thermo=50, start=None, temperature=2.0,
               radius=None, **extra) -> dict:
    """n atoms in a closed 10^3 box (fixed boundaries) started in the `start` region, walls from
    the region `R` (box units). Fast gas, so atoms reach and hit the walls."""
    d = gas(walls, n=n, steps=steps, thermo=thermo, hi=(L, L, L), temperature=temperature, **extra)
    d["box"]["boundary"] = ["f", "f", "f"]
    d["regions"] = {"R": {**region, "units": "box"}, "mid": {**(start or region), "units": "box"}}
    if radius is not None:
        d["atoms"][0]["radius"] = radius
    return d


def rwall(style: str, **over) -> dict:
    p = dict(STYLE_PARAMS[style])
    p.pop("radius", None)
    p.update(over)
    return {"style": "region", "region": "R", "potential": style, **p}


SPHERE_IN = {"style": "sphere", "center": [5.0, 5.0, 5.0], "radius": 4.5}
SPHERE_START = {"style": "sphere", "center": [5.0, 5.0, 5.0], "radius": 3.0}
BLOCK_IN = {"style": "block", "lo": [0.5, 0.5, 0.5], "hi": [9.5, 9.5, 9.5]}
BLOCK_START = {"style": "block", "lo": [2.0, 2.0, 2.0], "hi": [8.0, 8.0, 8.0]}
# outside regions: an obstacle in the middle; atoms start in a shell away from it
SPHERE_OUT = {"style": "sphere", "center": [5.0, 5.0, 5.0], "radius": 2.0, "side": "out"}
BLOCK_OUT = {"style": "block", "lo": [3.5, 4.0, 3.0], "hi": [6.5, 6.0, 7.0], "side": "out"}
CORNERS = {"style": "block", "lo": [0.0, 0.0, 0.0], "hi": [L, L, 2.5]}  # start under the obstacles


def cylinder(axis: str, side: str = "in", radius: float = 4.0, lo: float = 0.5, hi: float = 9.5) -> dict:
    return {"style": "cylinder", "axis": axis, "center": [5.0, 5.0], "radius": radius, "lo": lo, "hi": hi,
            "side": side}


def assert_hits(ref, *, key="region_force"):
    """The region walls really acted: their force on the wall is nonzero on some sample."""
    assert any(np.abs(r.data[key]).max() > 0 for r in ref if key in r.data), "no contact: the scene tests nothing"


# lj126 and lj1043 share a scene (two walls on the sphere): its kernel is the one of the LAMMPS
# lattice-unit regions test (tests/lammps/test_parity_issue4.py), not two kernels of their own
@pytest.mark.parametrize("styles", [("colloid",), ("harmonic",), ("lj1043", "lj126"), ("lj93",), ("morse",)],
                         ids="+".join)
def test_sphere_cavity_each_style(monkeypatch, styles):
    radius = 0.4 if styles == ("colloid",) else None
    over = {"epsilon": 30.0} if styles == ("harmonic",) else {}  # stiff enough to hold the gas
    walls = {f"rw{k}": rwall(style, **over) for k, style in enumerate(styles)}
    ref, _, _ = check(monkeypatch, [region_gas(SPHERE_IN, walls, start=SPHERE_START, radius=radius)])
    assert ref[0].status == "ok"
    for k in range(len(styles)):  # each wall acted
        assert np.abs(ref[0].data["region_force"][:, k]).max() > 0, styles[k]


@pytest.mark.parametrize("region,start", [(BLOCK_IN, BLOCK_START), (SPHERE_OUT, CORNERS), (BLOCK_OUT, CORNERS)],
                         ids=["block-in", "sphere-out", "block-out"])
def test_block_and_outside_regions(monkeypatch, region, start):
    """Block inside (up to 6 contacts per atom near a corner), sphere and block obstacles (one
    nearest-point contact: faces, edges, corners), lj93 with a long cut-off."""
    walls = {"rw": rwall("lj93", cutoff=3.0), "box": {"style": "reflect", "units": "box", "xlo": 0.0, "xhi": L,
                                                      "ylo": 0.0, "yhi": L, "zlo": 0.0, "zhi": L}}
    ref, _, _ = check(monkeypatch, [region_gas(region, walls, start=start, steps=600)])
    assert ref[0].status == "ok"
    assert_hits(ref)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
@pytest.mark.parametrize("side", ["in", "out"])
def test_cylinder_every_axis_both_sides(monkeypatch, axis, side):
    """Cylinder inside (curved wall + two caps) and outside (rim, caps, edges), along each axis."""
    if side == "in":
        region, start = cylinder(axis), cylinder(axis, radius=2.5, lo=2.5, hi=7.5)
        walls = {"rw": rwall("harmonic", epsilon=30.0, cutoff=1.5)}
    else:
        region, start = cylinder(axis, "out", radius=2.0, lo=3.0, hi=7.0), CORNERS
        # the walls of test_block_and_outside_regions (one kernel for both tests)
        walls = {"rw": rwall("lj93", cutoff=3.0), "box": {"style": "reflect", "units": "box", "xlo": 0.0, "xhi": L,
                                               "ylo": 0.0, "yhi": L, "zlo": 0.0, "zhi": L}}
    ref, _, _ = check(monkeypatch, [region_gas(region, walls, start=start, steps=500)])
    assert ref[0].status == "ok"
    assert_hits(ref)


def test_flat_walls_region_group_and_sweep(monkeypatch):
    """A batch of three cases (per-case epsilon and cut-off), a flat lj93 wall on z and a sphere
    region wall on one group only, plus a second region wall on all atoms: the kernel's order
    (flat walls, then region walls in config order) is the NumPy engine's. (lj126 and morse region
    walls: the kernel of the LAMMPS sphere-in-morse-cube test, tests/lammps/test_parity_issue4.py.)"""
    def cfg(eps, rc):
        d = region_gas(BLOCK_IN, {"rw": rwall("lj126", epsilon=eps, cutoff=rc),
                                  "ball": {**rwall("morse"), "region": "S", "group": "slow"},
                                  "floor": {"style": "lj93", "units": "box", "zlo": [0.0, 1.0, 1.0, 2.5]}},
                       start=SPHERE_START, steps=300)
        d["regions"]["S"] = {**SPHERE_IN, "units": "box"}
        d["atoms"] = [{"group": "fast", "create": {"random": {"count": 30, "region": "mid"}}, "mass": 1.0,
                       "velocity": {"temperature": 2.0}},
                      {"group": "slow", "create": {"random": {"count": 20, "region": "mid"}}, "mass": 2.5,
                       "velocity": {"temperature": 1.0}}]
        return d
    ref, _, _ = check(monkeypatch, [cfg(0.7, 2.5), cfg(1.4, 1.8), cfg(0.3, 3.0)])
    assert all(r.status == "ok" for r in ref)
    assert_hits(ref)


def test_atom_through_the_wall_reports_as_numpy(monkeypatch):
    """A weak harmonic region wall and a fast gas: atoms cross the surface; the case fails with the
    NumPy engine's own message (the compiled chunk hands back), the other case of the batch runs on."""
    def cfg(eps):
        return region_gas(SPHERE_IN, {"rw": rwall("harmonic", epsilon=eps, cutoff=0.5)}, start=SPHERE_START,
                          temperature=30.0, steps=400)
    ref, got, eng = check(monkeypatch, [cfg(0.01), cfg(500.0)])
    assert got[0].status == "failed" and "wrong side" in got[0].error
    assert got[1].status == "ok"
    assert eng.fast.fallbacks > 0


def test_refused_region_walls_stay_in_numpy(monkeypatch):
    """A variable parameter keeps the scene on the NumPy path (same results, nothing compiled)."""
    d = region_gas(SPHERE_IN, {"rw": {**rwall("lj93"), "epsilon": "v_eps"}}, start=SPHERE_START, steps=100,
                   variables={"eps": "1.0 + 0.001*step"})
    _, _, eng = check(monkeypatch, [d], compiled=False)
    assert eng.fast is None or eng.fast.compiled_chunks == 0


def test_kernel_contacts_match_region_geometry():
    """The kernel's per-atom contact lists (RB slots) equal RegionGeom.contacts bit for bit on atoms
    at faces, edges, corners, the centre and outside, for every kind of region."""
    from wallbatch.geometry.regions import RegionGeom
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.5, 10.5, (fast.BLOCK, 3))
    x[:8] = [[5, 5, 5], [0.5, 0.5, 0.5], [9.5, 5, 5], [5, 9.0, 0.6], [2, 5, 5], [5, 5, 0.5], [5, 5, 9.7], [7, 7, 7]]
    geoms = [RegionGeom("block", "in", (0.5, 0.5, 0.5), (9.5, 9.5, 9.5)),
             RegionGeom("block", "out", (3.0, 4.0, 2.0), (6.0, 7.0, 8.0)),
             RegionGeom("sphere", "in", center=(5.0, 5.0, 5.0), radius=4.5),
             RegionGeom("sphere", "out", center=(5.0, 5.0, 5.0), radius=2.0)]
    geoms += [RegionGeom("cylinder", side, 0.5, 9.5, (5.0, 5.0), 3.0 if side == "out" else 4.2, ax)
              for ax in range(3) for side in ("in", "out")]
    rc = 2.0
    for g in geoms:
        meta, geo, _ = fast.FastPath._regions(_Plan(g, len(x)), lambda grp, all_atoms: 0)
        RB = np.zeros((6, 5, fast.BLOCK))
        nslot, nwrong = fast._region_contacts(meta[0, 0], meta[0, 1], geo[0], np.ascontiguousarray(x.T),
                                              np.ones((1, len(x)), np.uint8), 0, rc, np.uint64(0),
                                              np.uint64(len(x)), RB)
        assert nwrong == int((~g.contains(x)).sum())
        ok = g.contains(x)
        idx, delta, r = g.contacts(x[ok], rc)
        idx = np.nonzero(ok)[0][idx]
        slots = RB[:nslot]
        flags = slots[:, 0, :] != 0
        got_atoms = np.nonzero(flags)  # (slot, atom) in slot-major order: the parts' order
        assert len(got_atoms[1]) == len(idx) > 0
        np.testing.assert_array_equal(got_atoms[1], idx)
        np.testing.assert_array_equal(slots[got_atoms[0], 1, got_atoms[1]], r)
        np.testing.assert_array_equal(slots[got_atoms[0], 2:, got_atoms[1]], delta)


class _Plan:
    """The part of a ChunkPlan FastPath._regions reads, for one region wall of lj93."""

    def __init__(self, geom, natoms):
        from wallbatch.styles import STYLES
        from wallbatch.styles.cutoff import CutoffStyle

        class W:
            pass
        w = W()
        w.geom, w.style, w.atoms = geom, STYLES["lj93"], np.arange(natoms)
        w.cutoff = CutoffStyle(w.style)
        w.params = {"epsilon": np.array([1.0]), "sigma": np.array([1.0]), "cutoff": np.array([2.5])}
        self.region = (w,)

        class S:
            ncases = 1
            x = np.zeros((1, natoms, 3))
        self.state = S()


def test_region_cutoff_modes(monkeypatch):
    """wall/region under the cut-off modes force-shift and smooth runs compiled (the registry's
    mode closures) and matches NumPy: one wall of each mode on the sphere (one kernel for both)."""
    walls = {"fs": {**rwall("lj93", cutoff=2.5), "cutoff_mode": "force-shift"},
             "sm": {**rwall("lj93", cutoff=2.5, epsilon=0.8), "cutoff_mode": "smooth", "switch_on": 1.5}}
    ref, _, _ = check(monkeypatch, [region_gas(SPHERE_IN, walls, start=SPHERE_START)])
    assert ref[0].status == "ok"
    for k in range(2):  # each wall acted
        assert np.abs(ref[0].data["region_force"][:, k]).max() > 0, list(walls)[k]
