"""Tests for wallbatch.geometry.regions: §5.1 contact geometry (hand-computed), fix wall/region against
LAMMPS 22Jul2025 (run 0 and short NVE runs), force = -grad E, the colloid decision, failures."""

from __future__ import annotations

import ctypes
import zlib

import numpy as np
import pytest
from lammps_oracle import _load_lammps, requires_lammps

from wallbatch.config.models import Region
from wallbatch.styles.flat import STYLES, shifted_energy_force
from wallbatch.geometry.regions import LAMMPS_MESSAGE, RegionGeom
from wallbatch.engine.region_walls import RegionWallKernel, lammps_region_colloid
from wallbatch.scene.case import RegionWallSpec
from wallbatch.units import lattice_constant

SQ = np.sqrt


# ----------------------------------------------------------------------------- helpers


class FakeState:
    """The part of engine.BatchState a region-wall kernel uses."""

    def __init__(self, x, radius=None, step=0, variables=None):
        self.x = np.array(x, float)
        C, N = self.x.shape[:2]
        self.f = np.zeros_like(self.x)
        self.radius = np.zeros((C, N)) if radius is None else np.broadcast_to(np.asarray(radius, float), (C, N))
        self.step = np.full(C, step, np.int64)
        self.failed: dict[int, str] = {}
        self.vars = variables or {}

    @property
    def ncases(self) -> int:
        return self.x.shape[0]

    def fail(self, rows, message) -> None:
        for c in np.atleast_1d(rows).tolist():
            self.failed.setdefault(int(c), message(int(c)))

    def variable(self, name):
        return self.vars[name]

    def at(self, c) -> str:  # (State.at outside minimize)
        return f"at step {int(self.step[c])}"


def make_kernel(geom, style, params, n, group=None, fix_id="rw", region="R", virial=False):
    """params: one dict per case."""
    grp = np.ones(n, bool) if group is None else group
    specs = [RegionWallSpec(fix_id, "region", region, geom, STYLES[style], grp, False, dict(p), virial)
             for p in params]
    return RegionWallKernel(specs)


def run_kernel(geom, style, params, x, radius=None, group=None):
    x = np.asarray(x, float)
    k = make_kernel(geom, style, params, x.shape[1], group)
    st = FakeState(x, radius)
    e, vec = k.apply(st, outputs=True)
    return e, vec, st


def sorted_contacts(geom, x, rc):
    idx, delta, r = geom.contacts(np.asarray(x, float), rc)
    order = np.lexsort((delta[:, 2], delta[:, 1], delta[:, 0], idx))
    return idx[order], delta[order], r[order]


BLOCK = {"style": "block", "lo": (1.0, 1.0, 1.0), "hi": (9.0, 9.0, 9.0)}
SPHERE = {"style": "sphere", "center": (5.0, 5.0, 5.0)}
CYL_Z = {"style": "cylinder", "axis": 2, "center": (5.0, 5.0), "radius": 3.0, "lo": 2.0, "hi": 8.0}


# ----------------------------------------------------------------------------- geometry by hand


def test_block_inside_contacts_faces_edges_corners():
    g = RegionGeom(**BLOCK)
    x = [[2.0, 5.0, 5.0],  # one face
         [1.5, 2.0, 8.5],  # corner: xlo 0.5, ylo 1, zhi 0.5
         [5.0, 5.0, 5.0],  # 4 from every face: nothing
         [0.5, 5.0, 5.0],  # outside: no contacts (wrong side)
         [1.0, 5.0, 5.0]]  # exactly on the xlo face: r = 0
    idx, delta, r = sorted_contacts(g, x, 2.5)
    np.testing.assert_array_equal(idx, [0, 1, 1, 1, 4])
    np.testing.assert_array_equal(r, [1.0, 0.5, 1.0, 0.5, 0.0])
    np.testing.assert_array_equal(delta, [[1, 0, 0], [0, 0, -0.5], [0, 1, 0], [0.5, 0, 0], [0, 0, 0]])
    # a small cube: all six faces act on its centre
    small = RegionGeom("block", lo=(0.0, 0.0, 0.0), hi=(2.0, 2.0, 2.0))
    idx, delta, r = sorted_contacts(small, [[1.0, 1.0, 1.0]], 1.5)
    assert idx.size == 6 and np.all(r == 1.0)
    np.testing.assert_array_equal(np.abs(delta).sum(axis=0), [2, 2, 2])
    np.testing.assert_array_equal(delta.sum(axis=0), [0, 0, 0])


def test_block_outside_nearest_point():
    g = RegionGeom(**BLOCK, side="out")
    x = [[0.0, 5.0, 5.0],  # face: del (-1, 0, 0)
         [0.0, 0.5, 5.0],  # edge: del (-1, -0.5, 0), r = sqrt(1.25)
         [0.0, 0.0, 0.0],  # corner: del (-1, -1, -1)
         [9.5, 9.0, 9.5],  # corner region but on the y = 9 plane: del (0.5, 0, 0.5)
         [5.0, 5.0, 5.0],  # strictly inside: nothing
         [9.0, 5.0, 5.0],  # on the surface: one contact, r = 0
         [5.0, 5.0, 11.5],  # farther than rc
         [-1.0, -1.0, 5.0]]  # |del| = 2 sqrt 2 > rc although each axis is within rc
    idx, delta, r = sorted_contacts(g, x, 2.5)
    np.testing.assert_array_equal(idx, [0, 1, 2, 3, 5])
    np.testing.assert_allclose(r, [1.0, SQ(1.25), SQ(3.0), SQ(0.5), 0.0], rtol=1e-15)
    np.testing.assert_array_equal(delta, [[-1, 0, 0], [-1, -0.5, 0], [-1, -1, -1], [0.5, 0, 0.5], [0, 0, 0]])


def test_sphere_inside_and_outside():
    g_in = RegionGeom(**SPHERE, radius=4.0)
    x = [[6.0, 5.0, 5.0],  # r = 3: del from (9,5,5) to the atom = (-3, 0, 0)
         [5.0, 5.0, 8.5],  # r = 0.5, del (0, 0, -0.5)
         [5.0, 5.0, 5.0],  # the centre feels nothing
         [5.0, 9.0, 5.0],  # on the surface: r = 0
         [5.0, 9.5, 5.0]]  # outside: nothing
    idx, delta, r = sorted_contacts(g_in, x, 3.5)
    np.testing.assert_array_equal(idx, [0, 1, 3])
    np.testing.assert_allclose(r, [3.0, 0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(delta, [[-3, 0, 0], [0, 0, -0.5], [0, 0, 0]], atol=1e-15)
    # off-axis point: delta is radial, pointing inward from the surface, |delta| = r
    small = RegionGeom(**SPHERE, radius=2.0)  # rc > R: the centre would be within reach
    idx, _, r = small.contacts(np.array([[5.0, 5.0, 5.0], [5.0, 5.0, 5.5]]), 2.5)
    assert idx.tolist() == [1] and r.tolist() == [1.5]
    p = np.array([[7.0, 6.0, 4.0]])
    idx, delta, r = g_in.contacts(p, 2.5)
    rho = SQ(6.0)
    assert r[0] == pytest.approx(4.0 - rho, rel=1e-15)
    np.testing.assert_allclose(delta[0], -(4.0 - rho) * np.array([2.0, 1.0, -1.0]) / rho, rtol=1e-14)

    g_out = RegionGeom(**SPHERE, radius=2.0, side="out")
    x = [[8.0, 5.0, 5.0], [5.0, 5.0, 5.0], [5.0, 3.0, 5.0], [5.0, 5.0, 9.6], [6.5, 6.5, 6.5]]
    idx, delta, r = sorted_contacts(g_out, x, 2.5)
    np.testing.assert_array_equal(idx, [0, 2, 4])
    np.testing.assert_allclose(r, [1.0, 0.0, 1.5 * SQ(3) - 2.0], rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(delta[0], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(delta[2], (1.5 * SQ(3) - 2.0) / SQ(3) * np.ones(3), rtol=1e-14)


def test_cylinder_inside_up_to_three_contacts():
    g = RegionGeom(**CYL_Z)
    x = [[7.0, 5.0, 3.0],  # curved r 1 del (-1,0,0); lo cap r 1 del (0,0,1)
         [5.0, 5.0, 5.0],  # on the axis: caps only (3 each)
         [5.0, 5.0, 8.0],  # on the hi cap: r = 0
         [8.5, 5.0, 5.0],  # outside radially: nothing
         [5.0, 5.0, 1.5]]  # below lo: nothing
    idx, delta, r = sorted_contacts(g, x, 3.5)
    np.testing.assert_array_equal(idx, [0, 0, 1, 1, 2])
    np.testing.assert_allclose(r, [1.0, 1.0, 3.0, 3.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(delta, [[-1, 0, 0], [0, 0, 1], [0, 0, -3], [0, 0, 3], [0, 0, 0]], atol=1e-15)
    thin = RegionGeom("cylinder", axis=2, center=(5.0, 5.0), radius=2.0, lo=0.0, hi=10.0)
    idx, delta, r = thin.contacts(np.array([[5.0, 5.0, 5.0], [5.0, 6.0, 5.0]]), 2.5)  # axis: no curved contact
    assert idx.tolist() == [1] and r.tolist() == [1.0] and delta.tolist() == [[0.0, -1.0, 0.0]]
    short = RegionGeom("cylinder", axis=2, center=(5.0, 5.0), radius=1.0, lo=4.0, hi=6.0)
    idx, delta, r = short.contacts(np.array([[5.5, 5.0, 5.0]]), 1.5)
    np.testing.assert_allclose(np.sort(r), [0.5, 1.0, 1.0])
    np.testing.assert_allclose(delta.sum(axis=0), [-0.5, 0, 0])


def test_cylinder_outside_rim_side_cap():
    g = RegionGeom(**CYL_Z, side="out")
    x = [[9.0, 5.0, 8.5],  # rim (edge): del (1, 0, 0.5)   (§15: F = (2.4721, 0, 1.2361))
         [9.0, 5.0, 5.0],  # curved side: del (1, 0, 0)
         [5.0, 6.0, 9.0],  # hi cap: del (0, 0, 1)
         [4.0, 5.0, 1.0],  # lo cap: del (0, 0, -1)
         [6.0, 5.0, 5.0],  # strictly inside
         [8.0, 5.0, 5.0],  # on the curved surface: r = 0
         [5.0, 5.0, 11.0]]  # beyond rc of the cap
    idx, delta, r = sorted_contacts(g, x, 2.5)
    np.testing.assert_array_equal(idx, [0, 1, 2, 3, 5])
    np.testing.assert_allclose(r, [SQ(1.25), 1.0, 1.0, 1.0, 0.0], rtol=1e-15)
    np.testing.assert_allclose(delta, [[1, 0, 0.5], [1, 0, 0], [0, 0, 1], [0, 0, -1], [0, 0, 0]], atol=1e-15)


@pytest.mark.parametrize("axis", [0, 1])
def test_cylinder_axis_maps_center_to_the_other_dims(axis):
    """axis x: center = (y, z); axis y: center = (x, z) (LAMMPS c1 c2 order)."""
    g = RegionGeom("cylinder", axis=axis, center=(3.0, 6.0), radius=2.0, lo=1.0, hi=9.0)
    o1, o2 = [d for d in range(3) if d != axis]
    x = np.zeros((1, 3))
    x[0, axis], x[0, o1], x[0, o2] = 5.0, 3.0, 7.5  # 1.5 from the axis along o2
    idx, delta, r = g.contacts(x, 1.0)
    assert idx.tolist() == [0] and r[0] == pytest.approx(0.5)
    expect = np.zeros(3)
    expect[o2] = -0.5
    np.testing.assert_allclose(delta[0], expect, atol=1e-15)
    assert g.contains(x).tolist() == [True]


def test_contains_is_the_side_test_surface_included_inside():
    cases = [(BLOCK, [1.0, 5.0, 9.0]), (dict(SPHERE, radius=4.0), [9.0, 5.0, 5.0]), (CYL_Z, [8.0, 5.0, 5.0]),
             (CYL_Z, [5.0, 5.0, 2.0])]
    for kw, on in cases:
        g_in, g_out = RegionGeom(**kw), RegionGeom(**kw, side="out")
        far = [9.9, 9.9, 9.9]
        mid = [5.0, 5.0, 5.0]
        assert g_in.contains(np.array([on, mid, far])).tolist() == [True, True, False]
        assert g_out.contains(np.array([on, mid, far])).tolist() == [False, False, True]
        assert g_in.distance(np.array(on)) == 0.0
    # broadcasting over (C, N, 3)
    assert RegionGeom(**BLOCK).contains(np.full((2, 4, 3), 5.0)).shape == (2, 4)


def test_distance_both_sides():
    g = RegionGeom(**BLOCK)
    np.testing.assert_allclose(g.distance(np.array([[2.0, 5.0, 5.0], [0.0, 0.5, 5.0], [5.0, 5.0, 5.0]])),
                               [1.0, SQ(1.25), 4.0])
    c = RegionGeom(**CYL_Z, side="out")
    np.testing.assert_allclose(c.distance(np.array([[9.0, 5.0, 8.5], [6.0, 5.0, 3.0], [5.0, 5.0, 1.0]])),
                               [SQ(1.25), 1.0, 1.0])
    s = RegionGeom(**SPHERE, radius=2.0)
    np.testing.assert_allclose(s.distance(np.array([[5.0, 5.0, 5.0], [9.0, 5.0, 5.0]])), [2.0, 2.0])


def test_cutoff_per_atom():
    g = RegionGeom(**BLOCK)
    x = np.array([[2.0, 5.0, 5.0], [2.0, 5.0, 5.0]])
    idx, _, _ = g.contacts(x, np.array([1.0, 1.0000001]))  # d < rc is strict
    assert idx.tolist() == [1]


def test_from_config_lattice_and_box_units():
    a = lattice_constant("fcc", 0.8442, "lj")
    blk = RegionGeom.from_config(Region(style="block", lo=(1, 2, 3), hi=(4, 5, 6)), a)
    assert blk.lo == (a, 2 * a, 3 * a) and blk.hi == (4 * a, 5 * a, 6 * a) and blk.side == "in"
    cyl = RegionGeom.from_config(Region(style="cylinder", axis="y", center=(1, 2), radius=3, lo=0.5, hi=7,
                                        side="out"), a)
    assert (cyl.axis, cyl.center, cyl.radius, cyl.lo, cyl.hi, cyl.side) == (1, (a, 2 * a), 3 * a, 0.5 * a, 7 * a, "out")
    sph = RegionGeom.from_config(Region(style="sphere", center=(1, 2, 3), radius=2, units="box"), a)
    assert (sph.center, sph.radius) == ((1.0, 2.0, 3.0), 2.0)
    assert RegionGeom.from_config(Region(style="sphere", center=(1, 2, 3), radius=2, units="box"), None) == sph
    with pytest.raises(ValueError, match="units: box"):
        RegionGeom.from_config(Region(style="sphere", center=(1, 2, 3), radius=2), None)


# ----------------------------------------------------------------------------- §15 numbers


def test_physics_section15_numbers():
    lj = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    # block 1..9, side in, atom 1.3 and 2.0 from two faces (LAMMPS: -0.4394023446565316)
    e, _, _ = run_kernel(RegionGeom(**BLOCK), "lj93", [lj], [[[2.3, 3.0, 5.0]]])
    assert e[0] == pytest.approx(-0.4394023446565316, rel=1e-14)
    # exterior block edge, harmonic eps 1: E = (rc - sqrt 1.25)^2
    e, vec, st = run_kernel(RegionGeom(**BLOCK, side="out"), "harmonic", [lj], [[[0.0, 0.5, 5.0]]])
    assert e[0] == pytest.approx(1.9098300562505257, rel=1e-14)
    np.testing.assert_allclose(st.f[0, 0], [-2.47213595, -1.23606798, 0.0], atol=5e-9)
    np.testing.assert_allclose(vec[0], -st.f[0, 0], rtol=1e-15)
    # exterior cylinder rim
    e, vec, st = run_kernel(RegionGeom(**CYL_Z, side="out"), "harmonic", [lj], [[[9.0, 5.0, 8.5]]])
    assert e[0] == pytest.approx(1.9098300562505257, rel=1e-14)
    np.testing.assert_allclose(st.f[0, 0], [2.47213595, 0.0, 1.23606798], atol=5e-9)


# ----------------------------------------------------------------------------- LAMMPS parity


def _num(v: float) -> str:
    return repr(float(v))


def lammps_region(g: RegionGeom) -> str:
    if g.style == "block":
        body = "block " + " ".join(f"{_num(g.lo[d])} {_num(g.hi[d])}" for d in range(3))
    elif g.style == "sphere":
        body = "sphere " + " ".join(_num(v) for v in (*g.center, g.radius))
    else:
        body = f"cylinder {'xyz'[g.axis]} " + " ".join(_num(v) for v in (*g.center, g.radius, g.lo, g.hi))
    return f"{body} units box side {g.side}"


def lammps_fix_args(style: str, p: dict) -> str:
    keys = ("D0", "alpha", "r0", "cutoff") if style == "morse" else ("epsilon", "sigma", "cutoff")
    return style + " " + " ".join(_num(p[k]) for k in keys)


def lammps_session(x, radius=None, region: str | None = None, box=10.0, boundary="f f f", v=None,
                   pre: tuple[str, ...] = ()):
    """A LAMMPS instance with the atoms x (N,3) (and velocities v) in a [0, box]^3 box."""
    lammps = _load_lammps()
    lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    sphere = radius is not None
    for c in ("units lj", f"atom_style {'sphere' if sphere else 'atomic'}", "atom_modify map array",
              f"boundary {boundary}", *pre, f"region box block 0 {box} 0 {box} 0 {box} units box",
              "create_box 1 box"):
        lmp.command(c)
    if not sphere:
        lmp.command("mass 1 1.0")
    x = np.asarray(x, float)
    n = len(x)
    vel = None if v is None else np.asarray(v, float).ravel().tolist()
    assert lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, x.ravel().tolist(), vel) == n
    if sphere:
        lmp.command("set group all mass 1.0")
        lmp.scatter_atoms("radius", 1, 1, (ctypes.c_double * n)(*np.asarray(radius, float)))
    if region is not None:
        lmp.command(f"region R {region}")
    return lmp


def lammps_run0(lmp, fix_args: str) -> tuple[float, np.ndarray, np.ndarray]:
    """fix W all wall/region R <fix_args>; run 0 -> (f_W, f_W[1..3], per-atom f)."""
    lmp.command(f"fix W all wall/region R {fix_args}")
    lmp.command("run 0")
    e = lmp.extract_fix("W", 0, 0)
    vec = np.array([lmp.extract_fix("W", 0, 1, i) for i in range(3)])
    f = np.ctypeslib.as_array(lmp.gather_atoms("f", 1, 3)).reshape(-1, 3).copy()
    lmp.command("unfix W")
    return e, vec, f


# (region geometry, atoms on the allowed side near faces, edges, corners; far ones feel nothing)
PARITY_SCENES = {
    "block-in": (RegionGeom(**BLOCK), [[2.3, 3.0, 5.0], [1.5, 1.6, 1.7], [8.2, 5.0, 8.6], [5.0, 5.0, 5.0],
                                       [5.0, 5.1, 1.9], [8.8, 8.9, 8.7]]),
    "block-out": (RegionGeom(**BLOCK, side="out"), [[0.4, 5.0, 5.0], [0.3, 0.5, 5.0], [9.6, 9.5, 0.4],
                                                   [5.0, 5.0, 9.5], [0.2, 9.9, 9.8], [9.1, 4.0, 2.0]]),
    "sphere-in": (RegionGeom(**SPHERE, radius=4.0), [[5.0, 5.0, 5.0], [8.0, 5.0, 5.0], [5.0, 2.0, 6.0],
                                                    [7.0, 7.0, 7.0], [5.1, 5.2, 5.3], [4.2, 5.3, 1.6]]),
    "sphere-out": (RegionGeom(**SPHERE, radius=2.0, side="out"), [[8.0, 5.0, 5.0], [6.5, 6.5, 6.5],
                                                                  [5.0, 5.0, 0.7], [1.0, 1.0, 1.0],
                                                                  [3.5, 3.4, 5.2], [5.0, 7.3, 5.0]]),
    "cylinder-in": (RegionGeom(**CYL_Z), [[5.0, 5.0, 5.0], [7.5, 5.0, 2.5], [5.0, 7.2, 7.6], [6.0, 6.0, 5.0],
                                          [3.0, 4.0, 3.0], [3.2, 6.9, 7.7]]),
    "cylinder-out": (RegionGeom(**CYL_Z, side="out"), [[9.0, 5.0, 8.5], [9.0, 5.0, 5.0], [5.0, 6.0, 9.0],
                                                       [4.0, 5.0, 1.0], [1.5, 5.0, 1.5], [8.2, 8.2, 5.0],
                                                       [6.0, 4.5, 9.7]]),
    # radius < cutoff: the exact centre / axis feels nothing (no direction), a nearby atom does
    "small-sphere-in": (RegionGeom(**SPHERE, radius=2.0), [[5.0, 5.0, 5.0], [5.0, 5.0, 5.001], [6.0, 4.5, 5.5]]),
    "small-cylinder-in": (RegionGeom("cylinder", axis=2, center=(5.0, 5.0), radius=2.0, lo=0.5, hi=9.5),
                          [[5.0, 5.0, 5.0], [5.0, 5.002, 5.0], [6.0, 4.5, 1.5]]),
    "cylinder-x-in": (RegionGeom("cylinder", axis=0, center=(4.5, 5.5), radius=3.0, lo=2.0, hi=8.0),
                      [[2.5, 4.5, 7.8], [7.4, 2.0, 5.0], [5.0, 4.0, 5.0]]),
    "cylinder-y-out": (RegionGeom("cylinder", axis=1, center=(4.5, 5.5), radius=3.0, lo=2.0, hi=8.0,
                                  side="out"), [[4.5, 8.9, 5.5], [8.0, 1.0, 8.0], [0.8, 5.0, 5.5]]),
}

PARITY_PARAMS = {
    "lj93": [{"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, {"epsilon": 0.7, "sigma": 1.2, "cutoff": 3.1}],
    "lj126": [{"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, {"epsilon": 0.7, "sigma": 0.8, "cutoff": 3.1}],
    "lj1043": [{"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, {"epsilon": 0.7, "sigma": 0.9, "cutoff": 3.1}],
    "harmonic": [{"epsilon": 2.0, "sigma": 1.0, "cutoff": 2.5}, {"epsilon": 0.5, "sigma": 1.0, "cutoff": 3.1}],
    "morse": [{"D0": 1.5, "alpha": 2.0, "r0": 1.1, "cutoff": 3.0}, {"D0": 0.8, "alpha": 1.3, "r0": 0.9,
                                                                    "cutoff": 2.2}],
}


def assert_close(got, want, rtol=1e-10):
    got, want = np.asarray(got), np.asarray(want)
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * max(1.0, np.abs(want).max()))


@requires_lammps
@pytest.mark.parametrize("scene", list(PARITY_SCENES))
def test_run0_matches_lammps(scene):
    """Every style, two parameter sets as two cases of one batch: f_W, f_W[1..3], atom forces."""
    g, x = PARITY_SCENES[scene]
    x = np.asarray(x, float)
    lmp = lammps_session(x, region=lammps_region(g))
    try:
        for style, params in PARITY_PARAMS.items():
            e, vec, st = run_kernel(g, style, params, np.stack([x] * len(params)))
            assert not st.failed
            for c, p in enumerate(params):
                e_l, vec_l, f_l = lammps_run0(lmp, lammps_fix_args(style, p))
                assert e_l != 0.0 and np.abs(f_l).max() > 0  # the wall acts
                assert_close(e[c], e_l)
                assert_close(vec[c], vec_l)
                assert_close(st.f[c], f_l)
    finally:
        lmp.close()


@requires_lammps
def test_lattice_units_match_lammps():
    """Regions in lattice units (lattice fcc 0.8442): centres, bounds and radii scaled by the spacing."""
    a = lattice_constant("fcc", 0.8442, "lj")
    regions = {
        "sphere 3 3 3 2": Region(style="sphere", center=(3, 3, 3), radius=2),
        "cylinder x 3 3 2 1 5 side out": Region(style="cylinder", axis="x", center=(3, 3), radius=2, lo=1, hi=5,
                                                side="out"),
        "block 1 5 1.5 5 1 4.5": Region(style="block", lo=(1, 1.5, 1), hi=(5, 5, 4.5)),
    }
    rng = np.random.default_rng(3)
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    for cmd, reg in regions.items():
        g = RegionGeom.from_config(reg, a)
        x = rng.uniform(0.0, 10.0, (400, 3))
        x = x[g.contains(x) & (g.distance(x) > 0.5) & (g.distance(x) < 2.0)][:6]
        assert len(x) == 6
        lmp = lammps_session(x, pre=("lattice fcc 0.8442",))
        try:
            lmp.command(f"region R {cmd}")
            e_l, vec_l, f_l = lammps_run0(lmp, "lj93 1.0 1.0 2.5")
        finally:
            lmp.close()
        e, vec, st = run_kernel(g, "lj93", [p], x[None])
        assert e_l != 0.0
        assert_close(e[0], e_l)
        assert_close(vec[0], vec_l)
        assert_close(st.f[0], f_l)


@requires_lammps
def test_virial_matches_lammps_pressure():
    """fix_modify virial yes: W = sum over contacts of F r; at rest LAMMPS's press = W / (3 V)."""
    g, x = PARITY_SCENES["cylinder-out"]
    x = np.asarray(x, float)
    p = PARITY_PARAMS["lj93"][0]
    lmp = lammps_session(x, region=lammps_region(g))
    try:
        lmp.command(f"fix W all wall/region R {lammps_fix_args('lj93', p)}")
        lmp.command("fix_modify W virial yes")
        lmp.command("thermo_style custom step press")
        lmp.command("run 0")
        press = lmp.get_thermo("press")
    finally:
        lmp.close()
    k = make_kernel(g, "lj93", [p], len(x), virial=True)
    st = FakeState(x[None])
    k.apply(st, outputs=True)
    assert press != 0.0
    assert k.last_virial[0] / 3000.0 == pytest.approx(press, rel=1e-10)


COLLOID = {"epsilon": 1.3, "sigma": 1.0, "cutoff": 3.5}


@requires_lammps
def test_colloid_decision_and_lammps_quirk():
    """LAMMPS's region colloid (quirk #1) is pinned by lammps_region_colloid; wallbatch gives the
    fix wall/colloid value and a force that is -dE/dr."""
    g = RegionGeom("block", lo=(0.0, 0.0, 0.0), hi=(10.0, 10.0, 10.0))  # face xlo at r = 1.7
    x = np.array([[1.7, 5.0, 5.0]])
    lmp = lammps_session(x, radius=[0.5], region=lammps_region(g))
    try:
        e_l, vec_l, f_l = lammps_run0(lmp, lammps_fix_args("colloid", COLLOID))
        lmp.command(f"fix C all wall/colloid xlo 0.0 {_num(1.3)} 1.0 3.5 units box")
        lmp.command("run 0")
        e_flat = lmp.extract_fix("C", 0, 0)
    finally:
        lmp.close()
    p = {**COLLOID, "radius": 0.5}
    e_q, f_q = lammps_region_colloid(1.7, p)
    assert e_l == pytest.approx(0.013334192907494803, rel=1e-14)
    assert e_q == pytest.approx(e_l, rel=1e-13)
    assert f_l[0, 0] == pytest.approx(f_q, rel=1e-12) and f_q == pytest.approx(0.01498109, abs=5e-9)
    assert_close(vec_l, -f_l[0])
    # the quirk: LAMMPS's force is not -dE/dr of its energy (-dE/dr = 0.016106 here)
    h = 1e-5
    de = (lammps_region_colloid(1.7 + h, p)[0] - lammps_region_colloid(1.7 - h, p)[0]) / (2 * h)
    assert -de == pytest.approx(0.0161063, abs=1e-6) and abs(-de - f_q) > 1e-3
    # wallbatch: the wall/colloid physics
    e, vec, st = run_kernel(g, "colloid", [COLLOID], x[None], radius=0.5)
    assert e[0] == pytest.approx(-0.007237555410428977, rel=1e-13)
    assert e[0] == pytest.approx(e_flat, rel=1e-13)
    assert st.f[0, 0, 0] == pytest.approx(-0.01498109, abs=5e-9)  # pulled toward the wall
    np.testing.assert_allclose(vec[0], -st.f[0, 0], rtol=1e-15)
    e_p, _, _ = run_kernel(g, "colloid", [COLLOID], (x + [h, 0, 0])[None], radius=0.5)
    e_m, _, _ = run_kernel(g, "colloid", [COLLOID], (x - [h, 0, 0])[None], radius=0.5)
    assert st.f[0, 0, 0] == pytest.approx(-(e_p[0] - e_m[0]) / (2 * h), rel=1e-7)


def test_colloid_shift_uses_each_particles_radius():
    """E(rc) is subtracted per atom with its own R; energy is 0 just inside the cut-off."""
    g = RegionGeom(**SPHERE, radius=4.0)
    x = np.array([[[5.0, 5.0, 5.0 + 4.0 - 3.5 + 1e-9], [5.0, 5.0, 5.0 - 4.0 + 1.2]]])
    e, _, _st = run_kernel(g, "colloid", [COLLOID], x, radius=np.array([[0.4, 0.9]]))
    e_far = shifted_energy_force(STYLES["colloid"], 3.5 - 1e-9, {**COLLOID, "radius": 0.4})[0]
    e_near = shifted_energy_force(STYLES["colloid"], 1.2, {**COLLOID, "radius": 0.9})[0]
    assert abs(e_far) < 1e-9
    assert e[0] == pytest.approx(e_far + e_near, rel=1e-12)


# ----------------------------------------------------------------------------- short NVE runs


def verlet(kernel, x, v, dt, steps, wrap=None):
    """Velocity Verlet with unit masses and only the region wall, as LAMMPS fix nve does."""
    st = FakeState(x[None])
    st.v = v[None].copy()
    kernel.apply(st, outputs=False)
    for n in range(1, steps + 1):
        st.v += 0.5 * dt * st.f
        st.x += dt * st.v
        if wrap is not None:
            st.x %= wrap
        st.step[:] = n
        st.f[:] = 0.0
        e, vec = kernel.apply(st, outputs=True)
        st.v += 0.5 * dt * st.f
    assert not st.failed
    return st.x[0], st.v[0], e[0], vec[0]


RUNS = {
    "block-in-lj93": (RegionGeom("block", lo=(1.0, 1.0, 1.0), hi=(5.0, 6.0, 4.0)), "lj93",
                      {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, "f f f"),
    "sphere-in-lj126": (RegionGeom(**SPHERE, radius=3.0), "lj126",
                        {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}, "f f f"),
    "cylinder-in-morse": (RegionGeom("cylinder", axis=1, center=(5.0, 5.0), radius=2.5, lo=2.0, hi=8.0), "morse",
                          {"D0": 1.0, "alpha": 2.0, "r0": 1.0, "cutoff": 2.0}, "f f f"),
    "block-out-harmonic": (RegionGeom("block", lo=(3.0, 3.0, 3.0), hi=(7.0, 7.0, 7.0), side="out"), "harmonic",
                           {"epsilon": 5.0, "sigma": 1.0, "cutoff": 1.0}, "p p p"),
}


@requires_lammps
@pytest.mark.parametrize("name", list(RUNS))
def test_short_nve_run_matches_lammps(name):
    g, style, p, boundary = RUNS[name]
    rng = np.random.default_rng(7)
    box = 10.0
    n = 8
    x = rng.uniform(0.0, box, (3000, 3))
    dist = g.distance(x)
    x = x[g.contains(x) & (dist > 0.9) & (np.abs(x - box / 2).max(axis=1) < 4.5)][:n]
    assert len(x) == n
    v = rng.normal(0.0, 1.5, (n, 3))
    dt, steps = 0.005, 300
    lmp = lammps_session(x, region=lammps_region(g), boundary=boundary, v=v)
    try:
        lmp.command("neigh_modify every 1 delay 0 check no")  # wrap every step (regions are not wrapped)
        lmp.command(f"timestep {dt}")
        lmp.command("fix I all nve")
        lmp.command(f"fix W all wall/region R {lammps_fix_args(style, p)}")
        lmp.command(f"run {steps}")
        e_l = lmp.extract_fix("W", 0, 0)
        vec_l = np.array([lmp.extract_fix("W", 0, 1, i) for i in range(3)])
        x_l = np.ctypeslib.as_array(lmp.gather_atoms("x", 1, 3)).reshape(-1, 3).copy()
        v_l = np.ctypeslib.as_array(lmp.gather_atoms("v", 1, 3)).reshape(-1, 3).copy()
    finally:
        lmp.close()
    k = make_kernel(g, style, [p], n)
    x_w, v_w, e, vec = verlet(k, x, v, dt, steps, wrap=box if boundary == "p p p" else None)
    assert np.abs(v_l - v).max() > 0.1  # the walls turned atoms around
    assert_close(x_w, x_l, rtol=1e-9)
    assert_close(v_w, v_l, rtol=1e-9)
    assert_close(e, e_l, rtol=1e-9)
    assert_close(vec, vec_l, rtol=1e-9)


# ----------------------------------------------------------------------------- force = -grad E

FD_PARAMS = {
    "lj93": {"epsilon": 1.1, "sigma": 0.9, "cutoff": 2.5},
    "lj126": {"epsilon": 1.1, "sigma": 0.9, "cutoff": 2.5},
    "lj1043": {"epsilon": 1.1, "sigma": 0.9, "cutoff": 2.5},
    "harmonic": {"epsilon": 2.0, "sigma": 1.0, "cutoff": 2.5},
    "morse": {"D0": 1.5, "alpha": 2.0, "r0": 1.1, "cutoff": 2.5},
    "colloid": {"epsilon": 1.3, "sigma": 0.8, "cutoff": 2.5},
}


@pytest.mark.parametrize("scene", list(PARITY_SCENES)[:6])
@pytest.mark.parametrize("style", list(FD_PARAMS))
def test_force_is_minus_gradient_of_energy(scene, style):
    """Each random atom is its own case, so the per-case energy is that atom's: central
    differences of all atoms at once give every force component."""
    g, _ = PARITY_SCENES[scene]
    p = FD_PARAMS[style]
    rng = np.random.default_rng(zlib.crc32(f"{scene}/{style}".encode()))
    x = rng.uniform(0.0, 10.0, (4000, 3))
    idx, _, r = g.contacts(x, p["cutoff"])
    rmin = np.full(len(x), np.inf)
    np.minimum.at(rmin, idx, r)
    near_rc = np.zeros(len(x), bool)
    near_rc[idx[np.abs(r - p["cutoff"]) < 1e-3]] = True
    d = g.distance(x)
    ok = g.contains(x) & np.isfinite(rmin) & (rmin > 0.75) & ~near_rc & (d > 1e-3)
    x = x[ok][:40]
    assert len(x) == 40
    radius = 0.3 if style == "colloid" else None
    h = 1e-6

    def energy(xs):
        return run_kernel(g, style, [p] * len(xs), xs[:, None, :], radius=radius)[0]

    _, _, st = run_kernel(g, style, [p] * len(x), x[:, None, :], radius=radius)
    f = st.f[:, 0, :]
    assert np.abs(f).max() > 1e-3
    for dim in range(3):
        step = np.zeros(3)
        step[dim] = h
        fd = -(energy(x + step) - energy(x - step)) / (2 * h)
        np.testing.assert_allclose(f[:, dim], fd, rtol=1e-6, atol=1e-6 * np.abs(f).max())


# ----------------------------------------------------------------------------- failures and groups


def test_wrong_side_and_too_close_fail_only_their_case():
    g = RegionGeom(**BLOCK)
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    good = np.array([[2.0, 5.0, 5.0], [5.0, 3.0, 5.0], [5.0, 5.0, 8.0], [4.0, 4.0, 4.0]])
    x = np.stack([good] * 3)
    x[1, 2] = [5.0, 5.0, 9.5]  # case 1, atom 2: outside a side-in block, 0.5 from it
    x[1, 3] = [5.0, 9.75, 5.0]  # a second wrong-side atom in the same case: the first is named
    x[2, 1] = [5.0, 1.0, 5.0]  # case 2, atom 1: exactly on the ylo face
    k = make_kernel(g, "lj93", [p] * 3, 4, fix_id="cage", region="box1")
    st = FakeState(x, step=7)
    e, vec = k.apply(st, outputs=True)
    assert sorted(st.failed) == [1, 2]
    m1, m2 = st.failed[1], st.failed[2]
    for m in (m1, m2):
        assert "walls.cage" in m and "box1" in m and "step 7" in m and LAMMPS_MESSAGE in m
    assert "atom ID 3 " in m1 and "outside region box1" in m1 and "0.5 " in m1
    assert "atom ID 2 " in m2 and "distance 0 " in m2
    # case 0 is untouched by the others: same as alone
    e0, vec0, st0 = run_kernel(g, "lj93", [p], good[None])
    assert e[0] == e0[0] and np.array_equal(vec[0], vec0[0]) and np.array_equal(st.f[0], st0.f[0])
    assert e0[0] != 0.0


def test_side_out_on_surface_and_colloid_too_close():
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    g = RegionGeom(**SPHERE, radius=2.0, side="out")
    x = np.array([[[7.0, 5.0, 5.0], [9.0, 5.0, 5.0]], [[9.0, 5.0, 5.0], [5.0, 8.5, 5.0]]])
    _, _, st = run_kernel(g, "lj93", [p, p], x)
    assert list(st.failed) == [0]
    assert "atom ID 1 " in st.failed[0] and "inside (or on the surface of) region R (side out)" in st.failed[0]
    # colloid: r <= R is too close, r just above R is fine
    g = RegionGeom(**BLOCK)
    x = np.array([[[1.5, 5.0, 5.0]], [[1.50001, 5.0, 5.0]]])
    _, _, st = run_kernel(g, "colloid", [COLLOID] * 2, x, radius=0.5)
    assert list(st.failed) == [0]
    assert "radius 0.5" in st.failed[0] and "atom ID 1 " in st.failed[0] and LAMMPS_MESSAGE in st.failed[0]
    # zero radius: LAMMPS refuses the run
    _, _, st = run_kernel(g, "colloid", [COLLOID], np.array([[[2.0, 5.0, 5.0]]]), radius=0.0)
    assert "requires only extended particles" in st.failed[0]


def test_group_mask_ignores_other_atoms():
    g = RegionGeom(**BLOCK)
    p = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    x = np.array([[[2.0, 5.0, 5.0], [0.5, 5.0, 5.0], [8.5, 5.0, 5.0]]])  # atom 1 outside, not in group
    grp = np.array([True, False, True])
    e, vec, st = run_kernel(g, "lj93", [p], x, group=grp)
    assert not st.failed
    assert np.all(st.f[0, 1] == 0.0) and st.f[0, 0, 0] != 0.0
    e1 = shifted_energy_force(STYLES["lj93"], 1.0, p)[0] + shifted_energy_force(STYLES["lj93"], 0.5, p)[0]
    assert e[0] == pytest.approx(e1, rel=1e-14)
    np.testing.assert_allclose(vec[0], -st.f[0].sum(axis=0), rtol=1e-15)


def test_variable_parameters_and_set_params():
    g = RegionGeom(**BLOCK)
    x = np.array([[[2.0, 5.0, 5.0]]] * 2)
    k = make_kernel(g, "harmonic", [{"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}] * 2, 1)
    k.set_params(epsilon="k")
    st = FakeState(x, variables={"k": np.array([3.0, -1.0])})
    e, _ = k.apply(st, outputs=True)
    assert e[0] == pytest.approx(3.0 * 1.5**2)
    assert list(st.failed) == [1] and "bad value" in st.failed[1]
    k.set_params(epsilon=np.array([2.0, 4.0]))
    k.take(np.array([1]))
    st = FakeState(x[1:])
    e, _ = k.apply(st, outputs=True)
    assert e[0] == pytest.approx(4.0 * 1.5**2) and st.f[0, 0, 0] == pytest.approx(2 * 4.0 * 1.5)
