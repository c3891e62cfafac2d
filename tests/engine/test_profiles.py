"""output.profiles / output.averages: config errors with file:line:col and field, binning, the
sample schedule, bit-identical batching, Boltzmann profile between harmonic walls (chi-square),
wall pressure of an ideal gas (soft and reflect walls), NetCDF round trip."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy import stats as sps

from wallbatch.api import load, run
from wallbatch.batch.runner import build_cases, run_config, run_plan
from wallbatch.config.models import config_from_dict, load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.engine.engine import Engine, run_cases
from wallbatch.engine.profiles import bin_index, bin_sums
from wallbatch.io.netcdf import write_netcdf
from wallbatch.scene.build import build_case

FILE = "p.yaml"
BASE = """\
box: {lo: [0, 0, 0], hi: [10, 10, 10], boundary: [p, p, f]}
atoms:
  - group: fluid
    create: {positions: [[5, 5, 5], [5, 5, 6]]}
    mass: 1.0
walls:
  w: {style: harmonic, units: box, zlo: [-1.0, 10.0, 1.0, 2.0], zhi: [11.0, 10.0, 1.0, 2.0]}
run: {steps: 1000, thermo: 10}
output:
"""
GOOD = "  profiles:\n    across: {axis: z, bins: 10, every: 10, repeat: 5, freq: 100, quantities: [temp]}\n"


def error(text: str) -> str:
    with pytest.raises(ConfigError) as info:
        load_config_text(text, FILE)
    assert len(info.value.problems) == 1, info.value.problems
    return info.value.problems[0]


def line_of(text: str, needle: str) -> int:
    return [i + 1 for i, ln in enumerate(text.splitlines()) if needle in ln][0]


@pytest.mark.parametrize("prof,needle,field,words", [
    ("{axis: z, bins: 10, every: 30, repeat: 2, freq: 100, quantities: [temp]}", "freq: 100",
     "output.profiles.across.freq", "multiple of every (30), as LAMMPS Nfreq and Nevery (LAMMPS: Inconsistent fix "
     "ave/chunk nevery/nrepeat/nfreq values)"),
    ("{axis: z, bins: 10, every: 10, repeat: 11, freq: 100, quantities: [temp]}", "repeat: 11",
     "output.profiles.across.repeat", "must not exceed freq (100): the samples of one window would overlap the "
     "previous one (LAMMPS: Inconsistent fix ave/chunk nevery/nrepeat/nfreq values)"),
    ("{axis: z, bins: 10, every: 0, repeat: 5, freq: 100, quantities: [temp]}", "every: 0",
     "output.profiles.across.every", "every must be >= 1 (LAMMPS: Illegal fix ave/chunk nevery value: 0)"),
    ("{axis: z, bins: 0, every: 10, repeat: 5, freq: 100, quantities: [temp]}", "bins: 0",
     "output.profiles.across.bins", "bins must be >= 1"),
    ("{axis: z, bins: 10, every: 10, repeat: 5, freq: 100, quantities: [temp, pressure]}", "quantities",
     "output.profiles.across.quantities.1", "density/number"),
    ("{axis: z, bins: 10, every: 10, repeat: 5, freq: 2000, quantities: [temp]}", "freq: 2000",
     "output.profiles.across.freq", "longer than the run"),
    ("{axis: z, bins: 10, every: 10, repeat: 5, freq: 100, quantities: [temp], group: gas}", "group: gas",
     "output.profiles.across.group", "unknown group 'gas'"),
    # more bins than memory allows (a MemoryError reported as a bug before)
    ("{axis: z, delta: 1e-10, every: 10, repeat: 5, freq: 100, quantities: [temp]}", "delta: 1e-10",
     "output.profiles.across.delta", "100,000,000,000 bins across the box's z (10 long): at most 1,000,000"),
    ("{axis: z, bins: 1000001, every: 10, repeat: 5, freq: 100, quantities: [temp]}", "bins: 1000001",
     "output.profiles.across.bins", "1,000,001 bins across the box's z"),
])
def test_bad_profiles_name_file_line_and_field(prof, needle, field, words):
    text = BASE + "  profiles:\n    across: " + prof + "\n"
    msg = error(text)
    assert msg.startswith(f"{FILE}:{line_of(text, needle)}:"), msg
    assert field in msg and words in msg, msg


def test_averages_start_past_the_end():
    text = BASE + GOOD + "  averages: {start: 1001}\n"
    msg = error(text)
    assert msg.startswith(f"{FILE}:{line_of(text, 'averages')}:") and "output.averages.start" in msg, msg
    assert "past the end of the run (1000 steps)" in msg
    load_config_text(BASE + GOOD + "  averages: {start: 1000}\n", FILE)  # inclusive: the last sample


def test_profiles_share_one_freq_and_averages_need_a_window():
    """Every profile's windows are on one `window` axis: two profiles with different freq are
    refused at the second one's freq (the run used to fail after computing every case); an
    averaging start after the last window is refused at `start` (the means were NaN)."""
    text = BASE + GOOD + "    along: {axis: x, bins: 4, every: 10, repeat: 2, freq: 200, quantities: [vx]}\n"
    msg = error(text)
    assert msg.startswith(f"{FILE}:{line_of(text, 'along:')}:") and "output.profiles.along.freq" in msg, msg
    assert "every profile's freq must be the same (across has 100, along has 200)" in msg
    load_config_text(text.replace("freq: 200", "freq: 100"), FILE)
    late = BASE.replace("steps: 1000", "steps: 1050") + GOOD + "  averages: {start: 1020}\n"
    msg = error(late)
    assert "output.averages.start" in msg and "after the last profile window (step 1000" in msg, msg
    load_config_text(late.replace("start: 1020", "start: 1000"), FILE)


def test_a_bad_profile_name_is_shown_at_its_key():
    """A name that is no word is a problem of the key: shown at the key's line and column (a
    problem of the profile's values stays at its first value), written in the file or in --set."""
    text = BASE + "  profiles:\n    bad name!:\n      axis: z\n      bins: 10\n      every: 10\n      repeat: 5\n" \
        "      freq: 100\n      quantities: [temp]\n"
    msg = error(text)
    assert msg.startswith(f"{FILE}:{line_of(text, 'bad name!')}:5: output.profiles.bad name!: profile name "), msg
    msg = error(text.replace("bad name!", "gap").replace("      bins: 10\n", ""))  # a problem of the values
    assert msg.startswith(f"{FILE}:{line_of(text, 'axis: z')}:7: output.profiles.gap: give exactly one of bins"), msg


def _sweep(tmp_path, sweep: str, scene: str = BASE + GOOD):
    (tmp_path / "p.yaml").write_text(scene)
    (tmp_path / "s.yaml").write_text("base: p.yaml\n" + sweep)
    return tmp_path / "s.yaml"


def test_a_sweep_is_checked_with_its_set_and_swept_values_in(tmp_path):
    """The cross-field checks run on the cases, after `set:` and the swept values: a base value
    they replace never runs and is no problem; a swept value that is one names its case."""
    bad = BASE + GOOD.replace("repeat: 5", "repeat: 20")  # 20 x 10 > freq 100
    assert "repeat" in error(bad)
    plan = load(_sweep(tmp_path, "set: {output.profiles.across.repeat: 5}\n"
                                 "sweep: {product: {e: {path: walls.w.zlo.epsilon, values: [10, 20]}}}\n", bad))
    assert [c.config.output.profiles["across"].repeat for c in plan.cases] == [5, 5]
    plan = load(_sweep(tmp_path, "sweep: {product: {r: {path: output.profiles.across.repeat, values: [2, 10]}}}\n",
                       bad))
    assert [c.config.output.profiles["across"].repeat for c in plan.cases] == [2, 10]
    with pytest.raises(ConfigError) as info:
        load(_sweep(tmp_path, "sweep: {product: {r: {path: output.profiles.across.repeat, values: [2, 11]}}}\n",
                    bad))
    (msg,) = info.value.problems
    assert msg.startswith("s.yaml:") or "s.yaml:" in msg, msg
    assert "output.profiles.across.repeat: repeat * every (11 * 10 = 110) must not exceed freq (100)" in msg
    assert msg.endswith("(case r=11)"), msg
    with pytest.raises(ConfigError, match=r"p\.yaml:\d+:\d+: output\.profiles\.across\.repeat: .* \(every case\)"):
        load(_sweep(tmp_path, "sweep: {product: {e: {path: walls.w.zlo.epsilon, values: [10, 20]}}}\n", bad))


def test_a_sweep_of_profile_windows_names_the_key_and_both_cases(tmp_path):
    """Cases share one `window` axis: a sweep of freq is refused by `check` (api.check) and by a
    run, naming the key that differs and the two cases."""
    from wallbatch.api import check
    from wallbatch.scene.case import CaseError

    path = _sweep(tmp_path, "set: {run.steps: 200}\n"
                            "sweep: {product: {f: {path: output.profiles.across.freq, values: [100, 200]}}}\n")
    words = r"case f=200 differs from case f=100 in output\.profiles\.across\.every, repeat or freq \(its windows\)"
    with pytest.raises(CaseError, match=words):
        check(load(path))
    with pytest.raises(CaseError, match=words):
        run_plan(load(path), tmp_path / "o.nc", jobs=1, progress=False)
    path = _sweep(tmp_path, "sweep: {product: {t: {path: run.thermo, values: [10, 20]}}}\n")
    with pytest.raises(CaseError, match=r"case t=20 differs from case t=10 in run\.thermo: the cases of a sweep"):
        check(load(path))


def test_bins_and_delta_exclusive_and_time_runs():
    msg = error(BASE + "  profiles:\n    across: {axis: z, bins: 10, delta: 0.5, every: 10, repeat: 5, freq: 100, "
                       "quantities: [temp]}\n")
    assert "output.profiles.across" in msg and "exactly one of bins" in msg
    msg = error(BASE + "  averages: {time: 3.0}\n")
    assert "output.averages.time" in msg and "start: STEP" in msg


def test_delta_bins_as_lammps_and_schedule():
    cfg = load_config_text(BASE + "  profiles:\n    across: {axis: z, delta: 0.3, every: 10, repeat: 3, freq: 100, "
                                  "quantities: [temp]}\n", FILE)
    p = build_case(cfg).profiles[0]
    assert p.nbins == 34 and p.delta == 0.3 and p.lo == 0.0  # ceil(10 / 0.3), last bin reaches past the box
    assert p.window_steps(1000) == list(range(100, 1001, 100))
    assert p.sample_steps(250) == [80, 90, 100, 180, 190, 200]


def test_bin_index_and_sums_per_case():
    coord = np.array([[0.0, 0.99, 1.0, 9.99, -0.5, 12.0], [0.5, 0.5, 2.5, 2.5, 2.5, 3.1]])
    b = bin_index(coord, np.array([0.0, 0.5]), np.array([1.0, 1.0]), 10)
    assert b.tolist() == [[0, 0, 1, 9, 0, 9], [0, 0, 2, 2, 2, 2]]
    w = np.arange(12.0).reshape(2, 6)
    rows = np.array([2, 0])  # live cases 2 and 0 of 3
    counts = bin_sums(b, rows, 10, 3)
    sums = bin_sums(b, rows, 10, 3, w)
    assert counts[1].sum() == 0 and counts[2].tolist()[:2] == [3, 1] and counts[0][2] == 4 and counts[0].sum() == 6
    assert sums[2][0] == 0 + 1 + 4 and sums[0][2] == 8 + 9 + 10 + 11


def ideal_gas(n: int, steps: int, walls: dict, profile: dict | None, sweep: dict | None = None,
              thermo: int = 10, start: int = 0, seed: int = 1) -> dict:
    cfg = {
        "seed": seed,
        "box": {"lo": [0, 0, 0], "hi": [8, 8, 10], "boundary": ["p", "p", "f"]},
        "regions": {"slab": {"style": "block", "lo": [0, 0, 3], "hi": [8, 8, 7], "units": "box"}},
        "atoms": [{"group": "gas", "create": {"random": {"count": n, "region": "slab"}}, "mass": 1.0,
                   "velocity": {"temperature": 1.0}}],
        "walls": walls, "timestep": 0.005,
        "run": {"steps": steps, "thermo": thermo},
        "output": {"averages": {"start": start}},
    }
    if profile:
        cfg["output"]["profiles"] = {"across": profile}
    if sweep:
        cfg["sweep"] = sweep
    return cfg


HARMONIC = {"w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 2.0, 1.0, 4.0], "zhi": [11.0, 2.0, 1.0, 4.0]}}


def harmonic_u(z: np.ndarray, k: float = 2.0) -> np.ndarray:
    """U(z) of the two harmonic walls: k (r - rc)^2 for r < rc, r = z + 1 (lo) and 11 - z (hi), rc = 4."""
    lo = np.clip(4.0 - (z + 1.0), 0, None)
    hi = np.clip(4.0 - (11.0 - z), 0, None)
    return k * (lo ** 2 + hi ** 2)


def boltzmann_positions(n: int, seed: int) -> list[list[float]]:
    """n positions in the 8 x 8 x 10 box with z drawn from exp(-U(z)/T), T = 1 (rejection)."""
    rng = np.random.default_rng(seed)
    z = np.empty(0)
    while z.size < n:
        cand = rng.uniform(0.0, 10.0, 4 * n)
        z = np.concatenate([z, cand[rng.uniform(size=cand.size) < np.exp(-harmonic_u(cand))]])
    return np.column_stack([rng.uniform(0, 8, n), rng.uniform(0, 8, n), z[:n]]).tolist()


@pytest.mark.slow
def test_boltzmann_profile_between_harmonic_walls_chi_square():
    """Ideal gas started from the canonical distribution (z from exp(-U/T), Maxwell velocities at
    T = 1): Hamiltonian dynamics keeps it canonical, so every window's density profile is
    rho(z) = N exp(-U(z)/T) / (A int exp(-U/T) dz) in expectation. An ideal gas without a
    thermostat never forgets its atoms' energies (each atom's motion is periodic), so the error
    bars come from independent replicas (positions and velocities drawn anew), not from the time
    series. Chi-square over the bins; the same data against a flat profile and against the profile
    at T = 1.3 must fail. The replicas are one sweep (a zip of seed and start positions), so they
    run as one batch, each case with its own velocity stream."""
    n, reps = 1000, 16
    prof = {"axis": "z", "bins": 20, "every": 20, "repeat": 10, "freq": 200, "quantities": ["density/number"]}
    cfg = ideal_gas(n, 4000, HARMONIC, prof, thermo=200)
    cfg["sweep"] = {"zip": {"dim": "replica", "params": {
        "seed": {"path": "seed", "values": [100 + r for r in range(reps)]},
        "start": {"path": "atoms.0.create.positions",
                  "values": [boltzmann_positions(n, 2026 + r) for r in range(reps)]}}}}
    cfg["atoms"][0]["create"] = {"positions": boltzmann_positions(n, 2026)}
    res = run_plan(load(cfg), progress=False, as_xarray=False)  # plain results: "start" is no coordinate
    assert res.dims["replica"] == reps and (res["status"].data == "ok").all()
    mean = res["profile_across_density_number_mean"]
    assert mean.dims == ("replica", "across_bin")
    profiles = mean.data
    mean = profiles.mean(axis=0)
    err = profiles.std(axis=0, ddof=1) / np.sqrt(reps)

    def expected(temp: float) -> np.ndarray:
        fine = np.linspace(0, 10, 200001)
        w = np.exp(-harmonic_u(fine) / temp)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(fine))])
        edges = np.interp(np.linspace(0, 10, 21), fine, cum)
        return n * np.diff(edges) / cum[-1] / (64.0 * 0.5)

    expect = expected(1.0)
    ok = expect > 0.02 * expect.max()  # bins the gas reaches
    chi2 = float((((mean[ok] - expect[ok]) / err[ok]) ** 2).sum())
    dof = int(ok.sum())
    print(f"chi2 = {chi2:.1f} for {dof} bins")
    assert sps.chi2.sf(chi2, dof) > 1e-3, (chi2, dof)
    for wrong in (np.full_like(expect, n / 640.0), expected(1.3)):
        assert sps.chi2.sf(float((((mean[ok] - wrong[ok]) / err[ok]) ** 2).sum()), dof) < 1e-6


@pytest.mark.slow
def test_wall_pressure_soft_equals_mid_density_times_t():
    """Ideal gas between harmonic walls: the mean force per area on each wall is rho_mid k T
    (hydrostatic balance, P = rho kT in the flat middle), and lo/hi have the same sign."""
    prof = {"axis": "z", "bins": 10, "every": 10, "repeat": 10, "freq": 100, "quantities": ["density/number", "temp"]}
    ds = run_config(config_from_dict(ideal_gas(500, 3000, HARMONIC, prof, thermo=5, start=500)))
    assert ds.status.item() == "ok"
    p = ds["wall_pressure_mean"].values
    s = ds["wall_pressure_sem"].values
    assert (p > 0).all()
    mid = ds["profile_across_density_number_mean"].sel(across_bin=slice(3.5, 6.5)).mean().item()
    temp = ds["temp_mean"].item()
    assert abs(p.mean() - mid * temp) < 0.1 * mid * temp
    assert (s > 0).all() and (s < 0.2 * p).all()
    # the same numbers by hand from wall_force
    f = ds["wall_force"].sel(sample=ds.step >= 500)
    by_hand = np.array([-f.isel(face=0).mean().item(), f.isel(face=1).mean().item()]) / 64.0
    np.testing.assert_allclose(p, by_hand, rtol=1e-12)


def test_wall_pressure_reflect_is_nkt_over_v():
    """Ideal gas in a box closed by reflect walls: kinetic energy is constant, so the mean
    impulse pressure on each face is N k T / V (T with 3N dof, no momentum constraint)."""
    walls = {"m": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}}
    cfg = ideal_gas(400, 4000, walls, None, thermo=20, start=0)
    cfg["output"]["thermo"] = ["step", "time", "dt", "temp", "ke", "reflect_impulse"]
    ds = run_config(config_from_dict(cfg))
    assert ds.status.item() == "ok"
    ke = ds["ke"].isel(sample=0).item()
    expect = 2.0 * ke / 3.0 / 640.0  # N kT / V with kT = 2 KE / (3N)
    p, s = ds["wall_pressure_mean"].values, ds["wall_pressure_sem"].values
    assert np.all(np.abs(p - expect) < 4 * s + 0.02 * expect), (p, s, expect)
    assert ds["wall_pressure_sem_converged"].values.all()
    # the mean is the total impulse over the total time
    imp = ds["reflect_impulse"].isel(sample=slice(1, None))
    total = float(ds["time"].isel(sample=-1))
    np.testing.assert_allclose(p, np.array([-imp.isel(face=0).sum(), imp.isel(face=1).sum()]) / total / 64.0,
                               rtol=1e-12)


@pytest.mark.parametrize("thermo,start", [(0, 0), (20, 0), (20, 200)])
def test_interval_output_means_skip_the_first_sample(thermo, start):
    """reflect_count / reflect_impulse hold the interval since the previous sample: the first
    sample (step 0, a 0 that is no interval) is not averaged in, so reflect_count_mean is the mean
    count per interval and reflect_impulse_mean agrees with wall_pressure_mean (the same
    intervals: those starting at or after averages.start). With thermo 0 (one interval) the mean
    was half the count; it is now NaN, as every mean of a single sample."""
    walls = {"m": {"style": "reflect", "units": "box", "zlo": "EDGE", "zhi": "EDGE"}}
    cfg = ideal_gas(200, 1000, walls, None, thermo=thermo, start=start)
    cfg["output"]["thermo"] = ["step", "time", "temp", "reflect_count", "reflect_impulse"]
    ds = run_config(config_from_dict(cfg))
    assert ds.status.item() == "ok"
    steps = ds["step"].values
    first = int(np.nonzero(steps >= start)[0][0])  # the intervals ending after it start at or after `start`
    counts = ds["reflect_count"].isel(sample=slice(first + 1, None))
    assert counts.sum() > 0
    if counts.sizes["sample"] == 1:  # thermo 0: one interval, no error bar (a one-sample mean is NaN)
        assert np.isnan(ds["reflect_count_mean"].values).all() and np.isnan(ds["reflect_impulse_mean"]).all()
        return
    np.testing.assert_allclose(ds["reflect_count_mean"].values, counts.mean("sample").values, rtol=1e-12)
    imp = ds["reflect_impulse"].isel(sample=slice(first + 1, None))
    np.testing.assert_allclose(ds["reflect_impulse_mean"].values, imp.mean("sample").values, rtol=1e-12)
    # equal intervals: the mean impulse per interval over the interval and the area is the pressure
    interval = float(ds["time"].isel(sample=-1) - ds["time"].isel(sample=-2))
    np.testing.assert_allclose(ds["reflect_impulse_mean"].values * np.array([-1.0, 1.0]) / interval / 64.0,
                               ds["wall_pressure_mean"].values, rtol=1e-12)
    assert ds["reflect_count_mean"].attrs["comment"] == f"sampling intervals that start at or after step {start}"


def test_failed_case_with_reflect_impulse_warns_nothing(recwarn):
    """A failed case's reflect wall pressure is NaN without numpy's 0/0 RuntimeWarning (it was
    printed with its source line on every run with a failed case)."""
    walls = {"m": {"style": "reflect", "units": "box", "zhi": "EDGE"},
             "w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 2.0, 1.0, 4.0]}}
    cfg = ideal_gas(20, 100, walls, None, sweep={"product": {"lo": {"path": "walls.w.zlo.coord",
                                                                    "values": [-1.0, 5.0]}}})
    cfg["output"]["thermo"] = ["step", "time", "temp", "reflect_impulse"]
    ds = run(cfg)
    assert list(ds.status.values) == ["ok", "failed"], ds.error.values
    assert np.isnan(ds["wall_pressure_mean"].isel(lo=1)).all()
    assert np.isfinite(ds["wall_pressure_mean"].isel(lo=0)).all()
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in recwarn]


def test_batching_is_bit_identical_and_netcdf_round_trip(tmp_path):
    prof = {"axis": "z", "bins": 10, "every": 5, "repeat": 4, "freq": 20, "quantities": ["density/number", "vx"]}
    cfg = ideal_gas(100, 100, HARMONIC, prof, sweep={"product": {"k": {"path": "walls.w.zlo.epsilon",
                                                                       "values": [2.0, 3.0, 4.0]}}})
    cases, errors = build_cases(load(cfg))
    assert not errors
    together = run_cases(cases)
    alone = run_cases([cases[1]])[0]
    for name in ("profile_across_density_number", "profile_across_vx"):
        assert together[1].data[name].shape == (5, 10)
        np.testing.assert_array_equal(together[1].data[name], alone.data[name])
    ds = run(cfg)
    path = tmp_path / "r.nc"
    write_netcdf(ds, path)
    back = xr.open_dataset(path)
    assert back["profile_across_vx_sem_converged"].dtype == bool
    assert back["profile_across_vx"].dims == ("k", "window", "across_bin")
    assert back["across_bin"].attrs["units"] == "1" and list(back["window_step"].values) == [20, 40, 60, 80, 100]
    np.testing.assert_array_equal(back["wall_pressure_sem"].values, ds["wall_pressure_sem"].values)
    assert back["temp_mean"].dims == ("k",) and back["wall_force_mean"].dims == ("k", "face")


def test_engine_holds_cases_x_windows_x_bins_floats():
    """The engine stores exactly one float64 per case, window and bin per quantity, plus one
    running sum per case and bin per accumulated sum (the memory benchmark's numbers)."""
    prof = {"axis": "z", "bins": 7, "every": 5, "repeat": 2, "freq": 10, "quantities": ["density/number", "vz"]}
    cfg = ideal_gas(30, 60, HARMONIC, prof, sweep={"product": {"k": {"path": "walls.w.zlo.epsilon",
                                                                     "values": [2.0, 3.0, 4.0, 5.0]}}})
    cases, _ = build_cases(load(cfg))
    eng = Engine(cases)
    eng.run()
    store = eng.profiles.out[0]
    assert {q: a.shape for q, a in store.items()} == {"density/number": (4, 6, 7), "vz": (4, 6, 7)}
    assert sum(a.nbytes for a in store.values()) == 2 * 4 * 6 * 7 * 8
    assert sorted(eng.profiles.sums[0]) == ["count", "vz"]


def test_failed_case_profiles_and_means_are_nan():
    """A case that fails mid-run keeps its grid place: NaN windows, NaN means, converged false;
    the other case is untouched (same numbers as run alone)."""
    prof = {"axis": "z", "bins": 10, "every": 5, "repeat": 2, "freq": 10, "quantities": ["density/number"]}
    walls = {"w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 2.0, 1.0, 4.0], "zhi": ["v_top", 2.0, 1.0, 4.0]}}
    cfg = ideal_gas(50, 100, walls, prof, sweep={"product": {"top": {"path": "variables.top",
                                                                     "values": ["11.0", "11.0 - ramp(0, 10.5)"]}}})
    cfg["variables"] = {"top": "11.0"}
    ds = run(cfg)
    assert list(ds.status.values) == ["ok", "failed"], ds.error.values
    bad = ds.isel(top=1)
    assert np.isnan(bad["profile_across_density_number"]).all()
    assert np.isnan(bad["profile_across_density_number_mean"]).all()
    assert not bad["profile_across_density_number_sem_converged"].any()
    assert np.isnan(bad["wall_pressure_mean"]).all() and np.isnan(bad["temp_sem"])
    good = ds.isel(top=0)
    assert np.isfinite(good["profile_across_density_number"]).all()
    np.testing.assert_allclose((good["profile_across_density_number"] * 64 * 1.0).sum("across_bin"), 50, rtol=1e-12)


@pytest.mark.parametrize("density", ["density/number", "density/mass", None])
def test_intensive_means_pool_the_windows_of_bins_empty_in_some(density):
    """A bin with no atom in a window reads 0 there (as LAMMPS), no temperature or velocity, so
    the plain mean of its windows would be wrong. With the profile's density/number the windows
    of such a bin are pooled, weighted by the atoms counted (sum n T / sum n; NaN where no window
    counted one); with only density/mass (atoms of other masses would weigh differently) or no
    density (a temperature of exactly 0 is then the sign) its mean, sem and flag are NaN, NaN,
    false. Bins occupied in every window keep the block average of their windows; densities
    keep theirs everywhere."""
    quantities = ["temp", "vz"] + ([density] if density else [])
    prof = {"axis": "z", "bins": 10, "every": 5, "repeat": 2, "freq": 10, "quantities": quantities}
    walls = {"w": {"style": "harmonic", "units": "box", "zlo": [-1.0, 2.0, 1.0, 4.0], "zhi": [11.0, 2.0, 1.0, 4.0]}}
    ds = run(ideal_gas(40, 400, walls, prof, start=100))
    assert ds.status.item() == "ok"
    late = ds.window_step >= 100
    temp = ds["profile_across_temp"].sel(window=late)
    empty = (temp == 0.0).any("window").values  # the gas starts in 3 < z < 7: the end bins are empty at times
    never = (temp == 0.0).all("window").values
    assert (empty & ~never).any() and not empty.all()
    mean, sem = ds["profile_across_temp_mean"].values, ds["profile_across_temp_sem"].values
    conv = ds["profile_across_temp_sem_converged"].values
    from wallbatch.stats import block_average
    ref = block_average(temp.transpose("across_bin", "window").values)
    np.testing.assert_array_equal(mean[~empty], ref.mean[~empty])
    np.testing.assert_array_equal(sem[~empty], ref.sem[~empty])
    vz = ds["profile_across_vz_mean"].values
    assert np.isfinite(vz[~empty]).all()
    if density == "density/number":
        n = ds["profile_across_density_number"].sel(window=late)
        assert ((n == 0.0) == (temp == 0.0)).all()
        pooled = (n * temp).sum("window") / n.sum("window")  # one window over all of them
        some = empty & ~never
        np.testing.assert_allclose(mean[some], pooled.values[some], rtol=1e-12)
        assert np.all(mean[some] > 0.1) and np.all(sem[some] > 0) and np.all(sem[some] < mean[some])
        assert np.isnan(mean[never]).all() and np.isnan(sem[never]).all() and not conv[never].any()
        np.testing.assert_allclose(vz[some], ((n * ds["profile_across_vz"].sel(window=late)).sum("window")
                                              / n.sum("window")).values[some], rtol=1e-12)
        assert "pooled" in ds["profile_across_temp_mean"].attrs["comment"]
    else:
        assert np.isnan(mean[empty]).all() and np.isnan(sem[empty]).all() and not conv[empty].any()
        assert np.isnan(vz[empty]).all() == (density is not None)
    if density:
        assert np.isfinite(ds[f"profile_across_{density.replace('/', '_')}_mean"]).all()


def test_two_d_profiles_per_area_and_two_dof():
    """dimension: 2 (LAMMPS adof = 2, bin 'volume' = box area * delta / L): with one bin and
    samples on the thermo steps, the profile temperature is the thermo temperature (2N - 2 dof)
    times (N - 1) / N, and density * area = N."""
    n = 40
    rng = np.random.default_rng(4)
    pos = np.column_stack([rng.uniform(0, 8, n), rng.uniform(2, 6, n), np.zeros(n)]).tolist()
    cfg = {
        "dimension": 2,
        "box": {"lo": [0, 0, -0.5], "hi": [8, 8, 0.5], "boundary": ["p", "f", "p"]},
        "atoms": [{"group": "gas", "create": {"positions": pos}, "mass": 1.0, "velocity": {"temperature": 1.0}}],
        "walls": {"w": {"style": "harmonic", "units": "box", "ylo": [-1.0, 2.0, 1.0, 4.0],
                        "yhi": [9.0, 2.0, 1.0, 4.0]}},
        "fixes": {"nve": {"style": "nve"}, "e2d": {"style": "enforce2d"}},
        "timestep": 0.005, "run": {"steps": 200, "thermo": 10},
        "output": {"profiles": {"one": {"axis": "y", "bins": 1, "every": 10, "repeat": 5, "freq": 50,
                                        "quantities": ["density/number", "temp"]},
                                "many": {"axis": "x", "delta": 0.5, "every": 10, "repeat": 5, "freq": 50,
                                         "quantities": ["density/number"]}}},
    }
    ds = run(cfg)
    assert ds.status.item() == "ok", ds.error.item()
    np.testing.assert_allclose(ds["profile_one_density_number"].values[:, 0] * 64.0, n, rtol=1e-12)
    np.testing.assert_allclose((ds["profile_many_density_number"] * 8 * 0.5).sum("many_bin"), n, rtol=1e-12)
    temp = ds["temp"].values
    steps = ds["step"].values
    for k, w in enumerate(ds["window_step"].values):
        picked = temp[(steps > w - 50) & (steps <= w)]
        assert picked.size == 5
        assert ds["profile_one_temp"].values[k, 0] == pytest.approx(picked.mean() * (n - 1) / n, rel=1e-12)
    with pytest.raises(ConfigError, match="output.profiles.one.axis: a 2-d simulation"):
        config_from_dict({**cfg, "output": {"profiles": {"one": {**cfg["output"]["profiles"]["one"], "axis": "z"}}}})
