"""wall/reflect/stochastic through the pipeline: config and fix-line forms and their errors, the
two-temperature profile of an ideal gas, per-case random streams, outputs, LAMMPS export."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbatch.config.models import load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.engine.engine import Engine, run_cases
from wallbatch.engine.stochastic import StochasticKernel
from wallbatch.lammps.export import export_case
from wallbatch.scene.build import build_case
from factories import assert_same_results, run_numpy_and_compiled

T_LO, T_HI = 2.0, 0.5


def scene(walls: str, *, count: int = 400, steps: int = 200, thermo: int = 50, seed: int = 5,
          outputs: str = "[step, temp, reflect_count, reflect_impulse]", height: float = 10.0) -> str:
    return (
        f"name: thermal\nunits: lj\nseed: {seed}\ntimestep: 0.005\n"
        f"box: {{lo: [0, 0, 0], hi: [10, 10, {height!r}], boundary: [p, p, f]}}\n"
        f"atoms:\n  - group: gas\n    create: {{random: {{count: {count}}}}}\n    mass: 1.0\n"
        "    velocity: {temperature: 1.0}\n"
        f"walls:\n{walls}run: {{steps: {steps}, thermo: {thermo}}}\noutput: {{thermo: {outputs}}}\n"
    )


DIFFUSIVE = (f"  hot: {{style: reflect/stochastic, rstyle: diffusive, seed: 77, units: box,\n"
             f"        zlo: {{coord: EDGE, temp: {T_LO}}}, zhi: {{coord: EDGE, temp: {T_HI}}}}}\n")


def test_fix_line_and_mapping_give_the_same_case():
    line = f'  hot: "fix hot all wall/reflect/stochastic diffusive 77 zlo EDGE {T_LO} 0 0 0 zhi EDGE {T_HI} 0 0 0 units box"\n'
    a = run_cases([build_case(load_config_text(scene(DIFFUSIVE)))])[0]
    b = run_cases([build_case(load_config_text(scene(line)))])[0]
    assert a.status == b.status == "ok"
    np.testing.assert_array_equal(a.data["temp"], b.data["temp"])
    np.testing.assert_array_equal(a.data["reflect_impulse"], b.data["reflect_impulse"])


@pytest.mark.parametrize(
    "walls,needle",
    [
        ("  w: {style: reflect/stochastic, rstyle: maxwell, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0}}\n",
         "rstyle maxwell needs one accommodation coefficient"),
        ("  w: {style: reflect/stochastic, rstyle: ccl, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0, accom: 0.5}}\n",
         "rstyle ccl needs three accommodation coefficients"),
        ("  w: {style: reflect/stochastic, rstyle: diffusive, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0, accom: 0.5}}\n",
         "accom is not used by rstyle diffusive"),
        ("  w: {style: reflect/stochastic, rstyle: maxwell, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0, accom: 1.5}}\n",
         "between 0 and 1"),
        ("  w: {style: reflect/stochastic, rstyle: diffusive, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0, vel: [0, 0, 1]}}\n",
         "must lie in the wall's plane"),
        ("  w: {style: reflect/stochastic, rstyle: diffusive, seed: 3, units: box, xlo: {coord: EDGE, temp: 1.0}}\n",
         "cannot use a xlo wall in periodic x"),
        ("  w: {style: reflect/stochastic, rstyle: diffusive, seed: 0, units: box, zlo: {coord: EDGE, temp: 1.0}}\n",
         "seed"),
        ('  w: "fix w all wall/reflect/stochastic diffusive 3 zlo EDGE 1.0 0 0"\n', "missing arguments for the zlo wall"),
        ('  w: "fix w all wall/reflect/stochastic cercignanilampis 3 zlo EDGE 1.0 0 0 0 0.5 0.5 0.5"\n',
         "LAMMPS spells the Cercignani-Lampis model ccl"),
        ("  w: {style: reflect/stochastic, rstyle: cercignanilampis, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0, "
         "accom: [0.5, 0.5, 0.5]}}\n", "rstyle: Input should be 'diffusive', 'maxwell' or 'ccl' (LAMMPS spells the "
         "Cercignani-Lampis model ccl"),
        ("  w: {style: reflect/stochastic, rstyle: Maxwel, seed: 3, units: box, zlo: {coord: EDGE, temp: 1.0}}\n",
         "rstyle: Input should be 'diffusive', 'maxwell' or 'ccl'"),
    ],
)
def test_errors_name_file_line_and_field(walls, needle):
    with pytest.raises(ConfigError) as err:
        load_config_text(scene(walls), "t.yaml")
    msg = str(err.value)
    assert needle in msg
    assert msg.startswith("t.yaml:1") and "walls.w" in msg  # file:line:col and the dotted path


@pytest.mark.slow
def test_two_temperature_profile():
    """Knudsen gas (no collisions) between diffusive walls at T_lo and T_hi: atoms moving up carry
    T_lo, atoms moving down T_hi, in every slab; flux balance n_up sqrt(T_lo) = n_down sqrt(T_hi)
    gives the up fraction sqrt(T_hi)/(sqrt(T_lo)+sqrt(T_hi)) and the temperature sqrt(T_lo T_hi)."""
    case = build_case(load_config_text(scene(DIFFUSIVE, count=1000, steps=1, thermo=0, height=2.0)))
    engine = Engine([case])
    engine.setup()
    engine.advance(20000, sample=False)  # 100 time units: atoms with |v_z| > 0.02 have met a wall
    snaps = []
    for _ in range(40):
        engine.advance(250, sample=False)
        snaps.append((engine.state.x[0].copy(), engine.state.v[0].copy()))
    x = np.concatenate([s[0] for s in snaps])
    v = np.concatenate([s[1] for s in snaps])
    n_eff = 1000 * 20  # snapshots 1.25 time units apart are correlated: count half of them
    up_frac = math.sqrt(T_HI) / (math.sqrt(T_LO) + math.sqrt(T_HI))
    for lo in (0.0, 0.5, 1.0, 1.5):
        slab = (x[:, 2] >= lo) & (x[:, 2] < lo + 0.5)
        up = slab & (v[:, 2] > 0)
        down = slab & (v[:, 2] < 0)
        k = n_eff * slab.mean()
        assert abs(up.sum() / slab.sum() - up_frac) < 4 * math.sqrt(up_frac * (1 - up_frac) / k)
        for sel, t in ((up, T_LO), (down, T_HI)):
            temp = np.mean(v[sel] ** 2)  # per component, m = kB = 1
            assert abs(temp - t) < 4 * t * math.sqrt(2 / (3 * k * sel.sum() / slab.sum())), (lo, temp, t)
        t_all = np.mean(v[slab] ** 2)
        assert abs(t_all - math.sqrt(T_LO * T_HI)) < 0.05


def test_streams_per_case_independent_of_batching():
    cfg = load_config_text(scene(DIFFUSIVE, steps=300))
    a, b = build_case(cfg, (0,)), build_case(cfg, (1,))
    together = run_cases([a, b])
    alone = [run_cases([a])[0], run_cases([b])[0]]
    for t, s in zip(together, alone):
        np.testing.assert_array_equal(t.data["temp"], s.data["temp"])
        np.testing.assert_array_equal(t.data["reflect_count"], s.data["reflect_count"])
    assert not np.array_equal(together[0].data["temp"], together[1].data["temp"])


def test_outputs_count_and_impulse():
    """Counts per face and sample; the impulse of a face is the momentum given to the wall along
    +dim: negative on zlo, positive on zhi; per reflection m(<|v_in|> + <|v_out|>) > 0."""
    r = run_cases([build_case(load_config_text(scene(DIFFUSIVE, steps=2000, thermo=500)))])[0]
    count, imp = r.data["reflect_count"][1:], r.data["reflect_impulse"][1:]
    assert count.shape == (4, 2) and np.all(count > 0)
    assert np.all(imp[:, 0] < 0) and np.all(imp[:, 1] > 0)
    # the outgoing part alone is sqrt(pi/2) sigma per reflection; the incoming adds about as much
    per = -imp[:, 0].sum() / count[:, 0].sum()
    assert per > math.sqrt(math.pi / 2 * T_LO)


WALLS = {
    "diffusive": DIFFUSIVE,
    "maxwell": ("  w: {style: reflect/stochastic, rstyle: maxwell, seed: 5, units: box,\n"
                "      zlo: {coord: EDGE, temp: 1.5, vel: [0.3, 0, 0], accom: 0.4}, zhi: {coord: EDGE, temp: 0.7, "
                "accom: 0.9}}\n"),
    "ccl": ("  w: {style: reflect/stochastic, rstyle: ccl, seed: 9, units: box,\n"
            "      zlo: {coord: EDGE, temp: 1.5, vel: [0.2, -0.1, 0], accom: [0.3, 0.8, 0.6]}, "
            "zhi: {coord: EDGE, temp: 0.5, accom: [1.0, 0.2, 0.5]}}\n"),
}


@pytest.mark.slow
@pytest.mark.parametrize("thermo", [100, 1])
@pytest.mark.parametrize("rstyle", ["diffusive", "maxwell", "ccl"])
def test_compiled_equals_numpy_bit_for_bit(rstyle, thermo, monkeypatch):
    """wall/reflect/stochastic in the compiled chunk kernel (one case per call with the case's
    generator, the same plain functions, the same draws in the same order): three cases in one
    batch (their own streams) give the NumPy engine's trajectories, counts and impulses bit for
    bit, with a wall/reflect fix before it and a soft wall in the scene; sampled every 100 steps or
    every step, the samples come from the kernel (sampled chunks)."""
    walls = ("  top: {style: reflect, units: box, zhi: 9.5}\n" + WALLS[rstyle]
             + "  soft: {style: harmonic, units: box, zlo: {coord: EDGE, epsilon: 3.0, cutoff: 0.5}}\n")
    cfg = load_config_text(scene(walls, count=300, steps=400, thermo=thermo))
    cases = [build_case(cfg, (k,)) for k in range(3)]
    numpy_res, compiled, engine = run_numpy_and_compiled(monkeypatch, cases)
    assert isinstance(engine.reflect[-1], StochasticKernel)
    assert engine.fast is not None and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0
    assert all(n.status == "ok" and n.data["reflect_count"][1:, 1:].sum() > 0 for n in numpy_res)
    assert_same_results(numpy_res, compiled)  # every output, bit for bit
    assert not np.array_equal(numpy_res[0].data["temp"], numpy_res[1].data["temp"])
    assert engine.fast.sampled_calls > 0 and len(engine.samples) == 1  # all but step 0's from the kernel


def test_compiled_path_declines_what_it_does_not_run():
    """A wall/reflect/stochastic fix before a wall/reflect one (the kernel reflects in the other
    order), or with dt/reset, runs in NumPy; alone it runs compiled."""
    case = build_case(load_config_text(scene(DIFFUSIVE)))
    assert Engine([case]).fast is not None
    later = DIFFUSIVE + "  top: {style: reflect, units: box, zhi: 9.5}\n"
    assert Engine([build_case(load_config_text(scene(later)))]).fast is None


def test_export_writes_the_fix_line():
    walls = ("  w: {style: reflect/stochastic, rstyle: ccl, seed: 9, units: box,\n"
             "      zlo: {coord: EDGE, temp: 1.5, vel: [0.2, 0, 0], accom: [0.3, 0.8, 0.6]}}\n")
    cfg = load_config_text(scene(walls))
    exp = export_case(cfg, build_case(cfg))
    assert "w all wall/reflect/stochastic ccl 9 zlo EDGE 1.5 0.2 0.0 0.0 0.3 0.8 0.6 units box" in exp.script
    assert any("wall/reflect/stochastic random numbers" in d for d in exp.decisions)


@pytest.mark.lammps
@pytest.mark.slow
def test_lammps_thermal_slit_statistics(tmp_path):
    """The exported scene in LAMMPS (its own random numbers, 4 seeds) and wallbatch (4 replicas):
    the time-averaged temperature between walls at T_lo and T_hi agrees within 4 standard errors
    (over replicas), and both are near sqrt(T_lo T_hi)."""
    from lammps_oracle import lammps_available  # noqa: PLC0415

    if not lammps_available():
        pytest.skip("LAMMPS Python module not usable")
    from wallbatch.lammps.validate import run_lammps  # noqa: PLC0415

    means = {"wallbatch": [], "lammps": []}
    for k in range(4):
        walls = (f"  hot: {{style: reflect/stochastic, rstyle: diffusive, seed: {101 + k}, units: box,\n"
                 f"        zlo: {{coord: EDGE, temp: {T_LO}}}, zhi: {{coord: EDGE, temp: {T_HI}}}}}\n")
        cfg = load_config_text(scene(walls, count=300, steps=12000, thermo=200, seed=31 + k, height=2.0,
                                     outputs="[step, temp]"))
        case = build_case(cfg)
        res = run_cases([case])[0]
        assert res.status == "ok", res.error
        ref = run_lammps(export_case(cfg, case, data_dir=tmp_path / f"r{k}"), tmp_path / f"r{k}")
        keep = slice(len(res.data["temp"]) // 2, None)  # the second half: equilibrated
        means["wallbatch"].append(res.data["temp"][keep].mean())
        means["lammps"].append(ref["temp"][keep].mean())
    w, lmp = np.array(means["wallbatch"]), np.array(means["lammps"])
    se = math.sqrt(w.var(ddof=1) / w.size + lmp.var(ddof=1) / lmp.size)
    assert abs(w.mean() - lmp.mean()) < 4 * se, (w, lmp)
    for m in (w.mean(), lmp.mean()):
        assert abs(m - math.sqrt(T_LO * T_HI)) < 0.05, (w, lmp)


@pytest.mark.parametrize("rstyle,accom", [("maxwell", "0.4"), ("ccl", "[0.3, 0.8, 0.6]")])
def test_maxwell_and_ccl_walls_run(rstyle, accom):
    """Every rule runs through the engine: the gas stays inside, reflections are counted, and a
    wall with accommodation 0 in every coefficient is specular (temperature conserved exactly
    as with wall/reflect, up to round-off)."""
    walls = (f"  w: {{style: reflect/stochastic, rstyle: {rstyle}, seed: 5, units: box,\n"
             f"      zlo: {{coord: EDGE, temp: 1.5, accom: {accom}}}, zhi: {{coord: EDGE, temp: 1.5, accom: {accom}}}}}\n")
    res = run_cases([build_case(load_config_text(scene(walls, steps=600, thermo=200)))])[0]
    assert res.status == "ok", res.error
    assert res.data["reflect_count"][1:].sum() > 0
    zero = "0.0" if rstyle == "maxwell" else "[0.0, 0.0, 0.0]"
    spec = run_cases([build_case(load_config_text(scene(walls.replace(accom, zero), steps=600, thermo=200)))])[0]
    np.testing.assert_allclose(spec.data["ke"], spec.data["ke"][0], rtol=1e-12)
