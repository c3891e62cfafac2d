"""Profiles against LAMMPS fix ave/chunk (norm all) on the same deterministic scene: every bin of
every window agrees to 1e-9 relative (ideal gas: trajectories are not chaotic)."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import pytest

from lammps_chunk import chunk_fixes, read_ave_chunk
from lammps_oracle import Scene, requires_lammps, run_lammps
from wallbatch.batch.runner import run_config
from wallbatch.config.models import config_from_dict

pytestmark = [requires_lammps, pytest.mark.lammps]

RTOL = 1e-9
QUANTITIES = ["density/number", "density/mass", "temp", "vx", "vy", "vz"]


def scene(units: str):
    rng = np.random.default_rng(18)
    n = 60
    x = np.column_stack([rng.uniform(0, 6, n), rng.uniform(0, 6, n), rng.uniform(1.5, 8.5, n)])
    v = rng.normal(size=(n, 3)) * (1.0 if units == "lj" else 2e-3)
    mass = np.where(np.arange(n) < 30, 1.0, 3.0)
    return x, v, mass


def configs(units: str, every: int, repeat: int, freq: int, steps: int) -> tuple[dict, Scene, list[tuple]]:
    x, v, mass = scene(units)
    dt = 0.005 if units == "lj" else 1.0
    cfg = {
        "units": units, "timestep": dt,
        "box": {"lo": [0, 0, 0], "hi": [6, 6, 10], "boundary": ["p", "p", "f"]},
        "atoms": [{"group": "light", "create": {"positions": x[:30].tolist()}, "mass": 1.0,
                   "velocity": {"values": v[:30].tolist()}},
                  {"group": "heavy", "create": {"positions": x[30:].tolist()}, "mass": 3.0,
                   "velocity": {"values": v[30:].tolist()}}],
        "walls": {"w": {"style": "lj93", "units": "box", "zlo": ["EDGE", 1.0, 1.0, 2.5],
                        "zhi": ["EDGE", 1.0, 1.0, 2.5]}},
        "run": {"steps": steps, "thermo": freq},
        "output": {"profiles": {
            "across": {"axis": "z", "delta": 0.7, "every": every, "repeat": repeat, "freq": freq,
                       "quantities": QUANTITIES},
            "side": {"axis": "x", "bins": 8, "every": every, "repeat": repeat, "freq": freq,
                     "quantities": ["density/number", "temp", "vx"], "group": "heavy"}}},
    }
    tmp = tempfile.mkdtemp(prefix="wb_chunk_")
    files = {"across": os.path.join(tmp, "across.txt"), "side": os.path.join(tmp, "side.txt")}
    fixes = ["fix w all wall/lj93 zlo EDGE 1.0 1.0 2.5 zhi EDGE 1.0 1.0 2.5 units box"]
    fixes += chunk_fixes("across", "all", "z", every, repeat, freq, QUANTITIES, files["across"], delta=0.7)
    fixes += chunk_fixes("side", "heavy", "x", every, repeat, freq, ["density/number", "temp", "vx"],
                         files["side"], bins=8)
    sc = Scene(units=units, box_lo=(0, 0, 0), box_hi=(6, 6, 10), boundary=("p", "p", "f"), x=x, v=v, mass=mass,
               groups={"heavy": np.arange(30, 60)}, fixes=fixes, timestep=dt, steps=steps,
               thermo_every=freq, outputs=["step"])
    return cfg, sc, files


@pytest.mark.parametrize("units,every,repeat,freq", [("lj", 2, 4, 10), ("lj", 5, 2, 10), ("real", 3, 3, 12)])
def test_profiles_match_fix_ave_chunk(units, every, repeat, freq):
    steps = 5 * freq
    cfg, sc, files = configs(units, every, repeat, freq, steps)
    ds = run_config(config_from_dict(cfg))
    assert ds.status.item() == "ok", ds.error.item()
    run_lammps(sc)
    for name, quantities in (("across", QUANTITIES), ("side", ["density/number", "temp", "vx"])):
        ref = read_ave_chunk(files[name])
        assert sorted(ref) == list(range(freq, steps + 1, freq))  # repeat > 1: no window at step 0
        assert list(ds["window_step"].values) == sorted(ref)
        coord = ref[freq]["Coord1"] * (6.0 if name == "side" else 1.0)  # `bins:` is LAMMPS units reduced
        np.testing.assert_allclose(ds[f"{name}_bin"].values, coord, rtol=1e-12, atol=1e-12)
        checked_empty = False
        for q in quantities:
            ours = ds[f"profile_{name}_{q.replace('/', '_')}"].values  # (window, bin)
            theirs = np.stack([ref[s][q] for s in sorted(ref)])
            assert ours.shape == theirs.shape
            scale = np.abs(theirs).max()
            np.testing.assert_allclose(ours, theirs, rtol=RTOL, atol=1e-12 * scale, err_msg=f"{name} {q}")
            empty = np.stack([ref[s]["Ncount"] for s in sorted(ref)]) == 0
            if empty.any():
                assert (ours[empty] == 0).all()  # empty bins are 0, not NaN, as LAMMPS
                checked_empty = True
        if name == "across":
            assert checked_empty  # the scene has empty bins next to the walls


def test_repeat_one_window_at_step_zero_is_lammps_only():
    """Pinned difference: LAMMPS with Nrepeat 1 also writes an average at step 0; wallbatch's
    first window ends at the first multiple of freq (issue 18 convention)."""
    cfg, sc, files = configs("lj", 5, 1, 5, 20)
    ds = run_config(config_from_dict(cfg))
    run_lammps(sc)
    ref = read_ave_chunk(files["across"])
    assert sorted(ref) == [0, 5, 10, 15, 20]
    assert list(ds["window_step"].values) == [5, 10, 15, 20]
    ours = ds["profile_across_density_number"].values
    np.testing.assert_allclose(ours, np.stack([ref[s]["density/number"] for s in (5, 10, 15, 20)]), rtol=RTOL)


def test_time_means_are_lammps_ave_running_or_one_window_over_all():
    """The time means of temp, vx, vy, vz against LAMMPS, on the scene with bins of 0.25 (some
    empty in some windows, next to the walls): in a bin occupied in every window, the plain mean
    of the windows, which is LAMMPS's `ave running` at the last window; in a bin empty in some
    window, the windows pooled by atoms counted, which is LAMMPS's one window over every sample
    (the windows' samples are contiguous here: every 2, repeat 5, freq 10); NaN where no window
    counted an atom (LAMMPS writes 0)."""
    cfg, sc, files = configs("lj", 2, 5, 10, 50)
    cfg["output"]["profiles"]["across"]["delta"] = 0.25
    sc.fixes = [f.replace("lower 0.7 ", "lower 0.25 ") for f in sc.fixes]
    whole, running = files["across"] + ".whole", files["across"] + ".running"
    sc.fixes += chunk_fixes("whole", "all", "z", 2, 25, 50, QUANTITIES, whole, delta=0.25)
    sc.fixes += [ln.replace("norm all", "norm all ave running")
                 for ln in chunk_fixes("running", "all", "z", 2, 5, 10, QUANTITIES, running, delta=0.25)]
    ds = run_config(config_from_dict(cfg))
    assert ds.status.item() == "ok", ds.error.item()
    run_lammps(sc)
    windows, one, ave = read_ave_chunk(files["across"]), read_ave_chunk(whole)[50], read_ave_chunk(running)[50]
    counted = np.stack([windows[s]["Ncount"] for s in sorted(windows)])
    full, never = (counted > 0).all(axis=0), (counted == 0).all(axis=0)
    some = ~full & ~never
    assert some.sum() >= 3 and full.sum() >= 10 and never.any()
    for q in ("temp", "vx", "vy", "vz"):
        ours = ds[f"profile_across_{q}_mean"].values
        np.testing.assert_allclose(ours[full], ave[q][full], rtol=RTOL, atol=1e-12, err_msg=q)
        np.testing.assert_allclose(ours[some], one[q][some], rtol=RTOL, atol=1e-12, err_msg=q)
        assert np.isnan(ours[never]).all() and (one[q][never] == 0).all()
    np.testing.assert_allclose(ds["profile_across_density_number_mean"].values, ave["density/number"], rtol=RTOL)
