"""wall/lepton and wall/table through the pipeline: config and fix-line forms, errors at
file:line:field, sweeps and batches, built-ins spelled out, convergence of fine tables, and
trajectories against LAMMPS (wallbatch validate) on slit scenes."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from factories import assert_same_results, run_numpy_and_compiled
from lammps_oracle import requires_lammps
from wallbatch.config.fixline import parse_fix_line, to_fix_line
from wallbatch.config.models import load_config, load_config_text
from wallbatch.config.source import ConfigError
from wallbatch.config.sweep import load_plan
from wallbatch.engine.engine import run_cases
from wallbatch.scene.build import build_case
from wallbatch.scene.case import structure_key
from wallbatch.styles import STYLES
from wallbatch.styles.table import TableError, WallTable, read_table, tabulate, write_table


def _builtin(name: str):
    """A registry style as energy_force(r, p) -> (E, F) on a parameter mapping."""
    def energy_force(r, p):
        return STYLES[name].energy_force(r, p)

    energy_force.__name__ = name
    return energy_force


harmonic = _builtin("harmonic")
lj93 = _builtin("lj93")


LJ = {"epsilon": 1.0, "sigma": 1.0}


def slit(walls: str, *, steps: int = 1000, thermo: int = 50, count: int = 200, extra: str = "") -> str:
    """An ideal gas in a slit z in [0, 6] (atoms start in [0.8, 5.2]), walls given as YAML."""
    return textwrap.dedent("""\
        name: slit
        units: lj
        seed: 7
        box: {lo: [0, 0, 0], hi: [8, 8, 6], boundary: [p, p, f]}
        regions:
          inner: {style: block, lo: [0, 0, 0.8], hi: [8, 8, 5.2], units: box}
        atoms:
          - group: gas
            create: {random: {count: %d, region: inner}}
            mass: 1.0
            velocity: {temperature: 2.0}
        walls:
        """ % count) + textwrap.indent(walls, "  ") + textwrap.dedent(f"""\
        run: {{steps: {steps}, thermo: {thermo}}}
        output: {{thermo: [step, temp, ke, pe, etot]}}
        """) + extra


TOP = "top: {style: reflect, units: box, zhi: EDGE}\n"  # keeps the gas in where a test has no zhi wall


def write(tmp_path: Path, text: str, name: str = "c.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def lj93_tables(tmp_path: Path, n: int = 400) -> Path:
    path = tmp_path / "walls.table"
    r, e, f = tabulate(lambda r: lj93(r, LJ), 0.4, 3.0, n)
    write_table(path, "LJ93", r, e, f)
    r, e, f = tabulate(lambda r: harmonic(r, {"epsilon": 20.0, "cutoff": 2.0}), 0.02, 2.0, n)
    write_table(path, "HARM", r, e, f, append=True)
    return path


def lepton_both_ways(monkeypatch, cases) -> tuple[tuple, tuple]:
    """(results, compiled path) of one Engine over `cases` with wall/lepton forced compiled
    (WALLBATCH_LEPTON_COMPILED=always), then forced NumPy (never: its path is None)."""
    from wallbatch.engine.engine import Engine  # noqa: PLC0415

    runs = []
    for mode in ("always", "never"):
        monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", mode)
        engine = Engine(cases)
        runs.append((engine.run(), engine.fast))
    return runs[0], runs[1]


def run_one(cfg):
    res = run_cases([build_case(cfg)])[0]
    assert res.status == "ok", res.error
    return res


# ------------------------------------------------------------------------------ forms and errors


def test_fix_line_forms_round_trip():
    line = 'fix 1 all wall/lepton xlo -5.0 "k*(r-rc)^2; k=100.0; rc=4.0" 4.0 zhi EDGE "exp(-r)" 2.0 units box'
    d = parse_fix_line(line, "1")
    assert d["xlo"] == {"coord": -5.0, "expression": "k*(r-rc)^2; k=100.0; rc=4.0", "cutoff": 4.0}
    assert parse_fix_line(to_fix_line("1", d), "1") == d
    line = "fix t all wall/table spline 500 zlo EDGE walls.table LJ93 2.5 zhi 6.0 walls.table HARM 2.0 pbc no"
    d = parse_fix_line(line, "t")
    assert (d["tabstyle"], d["N"], d["zhi"]["keyword"]) == ("spline", 500, "HARM")
    assert parse_fix_line(to_fix_line("t", d), "t") == d
    # params of the mapping form become Lepton definitions
    m = {"style": "lepton", "zlo": {"coord": "EDGE", "expression": "k*(r-rc)^2", "params": {"k": 2.0, "rc": 1.5},
                                    "cutoff": 1.5}}
    assert to_fix_line("w", m) == 'fix w all wall/lepton zlo EDGE "k*(r-rc)^2; k=2.0; rc=1.5" 1.5'


def test_mapping_and_fix_line_same_trajectory(tmp_path):
    tab = lj93_tables(tmp_path)
    a = slit(f"w: {{style: lepton, units: box, zlo: {{coord: EDGE, expression: 'k*(r-rc)^2', cutoff: 1.5, "
             f"params: {{k: 30.0, rc: 1.5}}}}}}\n"
             f"t: {{style: table, tabstyle: linear, N: 300, units: box, zhi: {{coord: EDGE, file: {tab.name}, "
             f"keyword: LJ93, cutoff: 2.5}}}}\n", steps=300)
    b = slit('w: "fix w all wall/lepton zlo EDGE \'k*(r-rc)^2; k=30.0; rc=1.5\' 1.5 units box"\n'
             f't: "fix t all wall/table linear 300 zhi EDGE {tab.name} LJ93 2.5 units box"\n', steps=300)
    ra, rb = run_one(load_config(write(tmp_path, a, "a.yaml"))), run_one(load_config(write(tmp_path, b, "b.yaml")))
    for key in ("etot", "wall_energy", "wall_force"):
        np.testing.assert_array_equal(ra.data[key], rb.data[key])


@pytest.mark.parametrize(
    "face,needle,field",
    [
        ("{coord: EDGE, expression: 'k*(r-rc)^2', cutoff: 1.5, params: {k: 3.0}}", "unknown name(s) 'rc'",
         "zlo.expression"),
        ("{coord: EDGE, expression: 'k*r^2 + sqr(r)', cutoff: 1.5, params: {k: 3.0}}", "unknown function 'sqr'",
         "zlo.expression"),
        ("{coord: EDGE, expression: '1/(r-1)', cutoff: 1.5}", "division by zero in the energy at r = 1.0",
         "zlo.expression"),
        ("{coord: EDGE, expression: 'r^2', cutoff: 1.5, params: {k: 3.0}}", "are not used", "zlo.expression"),
        ("{coord: EDGE, expression: 'log(r-1.5)', cutoff: 1.5}", "not finite at the cut-off", "zlo.expression"),
        ("{coord: EDGE, expression: 'cutoff*r^2', cutoff: 1.5, params: {cutoff: 3.0}}", "is the face's cut-off",
         "zlo.params.cutoff"),
    ],
)
def test_lepton_errors_name_file_line_and_field(face, needle, field):
    text = slit(f"w:\n  style: lepton\n  units: box\n  zlo: {face}\n")
    with pytest.raises(ConfigError) as err:
        load_config_text(text, "scene.yaml")
    msg = str(err.value)
    assert needle in msg
    line = next(i for i, t in enumerate(text.splitlines(), start=1) if t.strip() == f"zlo: {face}")
    assert msg.startswith(f"scene.yaml:{line}:") and f"walls.w.{field}" in msg, msg


def test_table_errors(tmp_path):
    tab = lj93_tables(tmp_path)
    cases = [
        ("nothere.table", "LJ93", 2.5, "file", "cannot read table file"),
        (tab.name, "NOPE", 2.5, "keyword", "no table section 'NOPE': give one of LJ93, HARM"),
        (tab.name, "LJ93", 3.5, "cutoff", "beyond the table's last distance 3 (LAMMPS: Fix wall/table wall cutoff "
                                          "is larger than table outer cutoff): give a cutoff <= 3, or a table"),
    ]
    for file, keyword, cutoff, field, needle in cases:
        text = slit(f"t:\n  style: table\n  tabstyle: spline\n  N: 100\n  units: box\n"
                    f"  zlo: {{coord: EDGE, file: {file}, keyword: {keyword}, cutoff: {cutoff}}}\n")
        with pytest.raises(ConfigError) as err:
            load_config(write(tmp_path, text))
        msg = str(err.value)
        assert needle in msg and f"walls.t.zlo.{field}" in msg and msg.startswith(f"{tmp_path / 'c.yaml'}:"), msg
    bad = tmp_path / "bad.table"
    bad.write_text("LJ93\nN 3\n\n1 1.0 0 0\n2 x 0 0\n3 3.0 0 0\n")
    text = slit("t:\n  style: table\n  tabstyle: linear\n  N: 100\n  units: box\n"
                "  zlo: {coord: EDGE, file: bad.table, keyword: LJ93, cutoff: 2.5}\n")
    with pytest.raises(ConfigError, match=r"bad.table:5: bad table line '2 x 0 0'"):
        load_config(write(tmp_path, text))


def test_swept_table_keyword_missing_is_named_at_the_sweep_line(tmp_path):
    """A swept section keyword the file lacks is the keyword's error, at its line in the sweep."""
    tab = lj93_tables(tmp_path)
    text = slit(f"t:\n  style: table\n  tabstyle: spline\n  N: 100\n  units: box\n"
                f"  zlo: {{coord: EDGE, file: {tab.name}, keyword: LJ93, cutoff: 2.5}}\n")
    text += "sweep:\n  product:\n    kw: {path: walls.t.zlo.keyword, values: [LJ93, NOPE]}\n"
    line = len(text.splitlines())
    with pytest.raises(ConfigError) as err:
        load_plan(write(tmp_path, text))
    assert str(err.value).splitlines()[-1] == (
        f"{tmp_path / 'c.yaml'}:{line}:45: walls.t.zlo.keyword: {tab}: no table section 'NOPE': give one of LJ93, "
        "HARM (case kw=NOPE)")


def test_atom_nearer_than_the_table_fails_its_case(tmp_path):
    tab = lj93_tables(tmp_path)
    text = slit(f"t: {{style: table, tabstyle: linear, N: 100, units: box, zlo: {{coord: 0.7, file: {tab.name}, "
                f"keyword: LJ93, cutoff: 2.5}}}}\n" + TOP, steps=10)
    res = run_cases([build_case(load_config(write(tmp_path, text)))])[0]
    assert res.status == "failed"
    delta = (3.0 - 0.4) / 99
    assert f"nearer than {0.4 - delta:g}, one table interval below the table's first distance 0.4" in res.error
    assert "Particle / wall distance < table inner cutoff" in res.error


def _reach_scene(tmp_path: Path, tabstyle: str, zs: list[float], steps: int = 20) -> Path:
    """Atoms at rest at distances zs from a zlo wall/table whose table (harmonic, epsilon 20,
    cut-off 3: F = 40 (3 - r)) starts at r = 0.9 with N = 22 (delta = 0.1): the distances in
    (0.8, 0.9) are in the first interval's extension."""
    path = tmp_path / "reach.table"
    r, e, f = tabulate(lambda r: harmonic(r, {"epsilon": 20.0, "cutoff": 3.0}), 0.9, 3.0, 50)
    write_table(path, "LJ93", r, e, f)
    pos = ", ".join(f"[{1.0 + k}, 4.0, {z!r}]" for k, z in enumerate(zs))
    return write(tmp_path, textwrap.dedent(f"""\
        name: reach
        units: lj
        box: {{lo: [0, 0, 0], hi: [8, 8, 6], boundary: [p, p, f]}}
        atoms:
          - {{group: a, create: {{positions: [{pos}]}}, mass: 1.0}}
        walls:
          t: {{style: table, tabstyle: {tabstyle}, N: 22, units: box, energy: true,
              zlo: {{coord: 0.0, file: reach.table, keyword: LJ93, cutoff: 2.5}}}}
          top: {{style: reflect, units: box, zhi: EDGE}}
        run: {{steps: {steps}, thermo: 1}}
        output: {{thermo: [step, pe, ke]}}
        """))


@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_table_reaches_one_interval_below_its_first_distance(tmp_path, monkeypatch, tabstyle):
    """As LAMMPS, an atom less than one table interval below the table's first distance lo gets
    the first interval's lookup extrapolated (the index int((r - lo)/delta) truncates to 0):
    force and energy at step 0 equal that extrapolation; the compiled path equals the NumPy
    path bit for bit; at (r - lo)/delta = -1 or below the case fails."""
    zs = [0.85, 0.8001, 0.95]
    cases = [build_case(load_config(_reach_scene(tmp_path, tabstyle, zs)))]
    ref, fast, engine = run_numpy_and_compiled(monkeypatch, cases)
    assert engine.fast is not None and engine.fast.compiled_chunks > 0
    assert ref[0].status == "ok", ref[0].error
    assert_same_results(ref, fast)
    t = WallTable.build(read_table(tmp_path / "reach.table", "LJ93"), tabstyle, 22)
    e, f = t.lookup(np.array(zs))
    i = np.array([0, 0, 0])  # the first interval for the two below lo, extrapolated
    if tabstyle == "linear":  # linearly: f[0] + (r - lo)/delta (f[1] - f[0])
        want = t.f[i] + (np.array(zs) - t.r[i]) * t.invdelta * t.df[i]
        np.testing.assert_allclose(f, want, rtol=1e-14)
    np.testing.assert_allclose(f, 40.0 * (3.0 - np.array(zs)), rtol=1e-9)  # a linear force: exact
    assert ref[0].data["wall_energy"][0] == pytest.approx(e.sum() - 3 * t.offset(2.5), rel=1e-13)
    assert ref[0].data["wall_force"][0, 0] == pytest.approx(-f.sum(), rel=1e-13)  # the atoms push the wall -z
    assert t.below(t.inner()) and not t.below(np.nextafter(t.inner(), 1.0))
    assert t.inner() == pytest.approx(0.8, abs=1e-14)
    with pytest.raises(TableError, match="extension down to"):
        t.lookup(np.array([0.79]))
    for numba in ("0", "1"):
        monkeypatch.setenv("WALLBATCH_NUMBA", numba)
        bad = run_cases([build_case(load_config(_reach_scene(tmp_path, tabstyle, [0.85, 0.7999], steps=5)))])[0]
        assert bad.status == "failed"
        assert "atom 1 at distance 0.7999 from the wall at step 0 is nearer than 0.8, one table interval" in bad.error


# ------------------------------------------------------------------------------ physics


def test_lepton_spelled_out_lj93_equals_builtin_run():
    face = "{coord: EDGE, cutoff: 2.5, expression: 'eps*(2/15*(sig/r)^9-(sig/r)^3)', params: {eps: 1.0, sig: 1.0}}"
    lep = slit(f"w: {{style: lepton, units: box, energy: true, zlo: {face}, zhi: {face}}}\n", steps=400)
    face = "{coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}"
    ref = slit(f"w: {{style: lj93, units: box, energy: true, zlo: {face}, zhi: {face}}}\n", steps=400)
    a, b = run_one(load_config_text(lep)), run_one(load_config_text(ref))
    # same physics to round-off; trajectories of an ideal gas with one wall stay close
    np.testing.assert_allclose(a.data["etot"], b.data["etot"], rtol=1e-11)
    np.testing.assert_allclose(a.data["wall_energy"], b.data["wall_energy"], rtol=1e-9, atol=1e-11)


def test_fine_table_converges_to_the_analytic_wall(tmp_path):
    """The same run with lj93 tables of 300, 1200, 4800 points (linear) approaches the built-in
    lj93 run: the error of the total energy falls with every refinement and by > 64x over the
    16x (linear interpolation: h^2 would give 256x; the trajectories' own differences add). Both
    faces are lj93 (no wall/reflect: the kernels of the other lj93 and table slits)."""
    face = "{coord: EDGE, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}"
    ref = run_one(load_config_text(slit(f"w: {{style: lj93, units: box, zlo: {face}, zhi: {face}}}\n", steps=200)))
    errs = []
    for n in (300, 1200, 4800):
        path = tmp_path / f"t{n}.table"
        r, e, f = tabulate(lambda r: lj93(r, LJ), 0.4, 3.0, n)
        write_table(path, "LJ93", r, e, f)
        tface = f"{{coord: EDGE, file: {path.name}, keyword: LJ93, cutoff: 2.5}}"
        text = slit(f"w: {{style: table, tabstyle: linear, N: {n}, units: box, zlo: {tface}, zhi: {tface}}}\n",
                    steps=200)
        res = run_one(load_config(write(tmp_path, text)))
        errs.append(np.max(np.abs(res.data["etot"] - ref.data["etot"])))
    assert errs[2] < 1e-4 * np.max(np.abs(ref.data["etot"]))
    assert errs[0] > errs[1] > errs[2] and errs[0] / errs[2] > 64, errs


def test_sweep_params_share_a_batch_and_differ(tmp_path):
    text = slit("w: {style: lepton, units: box, zlo: {coord: EDGE, cutoff: 1.5, expression: 'k*(r-rc)^2', "
                "params: {k: 30.0, rc: 1.5}}}\n" + TOP, steps=200,
                extra="sweep:\n  product:\n    k: {path: walls.w.zlo.params.k, values: [10.0, 30.0, 90.0]}\n")
    plan = load_plan(write(tmp_path, text))
    cases = [build_case(c.config, c.seed_key) for c in plan.cases]
    assert len({structure_key(c) for c in cases}) == 1
    together = run_cases(cases)
    alone = [run_cases([c])[0] for c in cases]
    for t, s in zip(together, alone):
        np.testing.assert_array_equal(t.data["etot"], s.data["etot"])  # batching changes nothing
    pe = [r.data["wall_energy"][1:].mean() for r in together]
    assert len(set(pe)) == 3
    other = slit("w: {style: lepton, units: box, zlo: {coord: EDGE, cutoff: 1.5, expression: 'k*(r-rc)^3', "
                 "params: {k: 30.0, rc: 1.5}}}\n")
    assert structure_key(build_case(load_config_text(other))) != structure_key(cases[0])


# ------------------------------------------------------------------------------ LAMMPS


def _validate(path: Path):
    from wallbatch.lammps.validate import validate_case  # noqa: PLC0415 - imports LAMMPS lazily

    report = validate_case(load_plan(path).cases[0])
    assert report.ok, report.text()
    return report


LEPTON_SLITS = {
    "harmonic": ("k*(r-rc)^2", "{k: 20.0, rc: 2.0}", 2.0),
    "lj126": ("4.0*eps*((sig/r)^12-(sig/r)^6)", "{eps: 1.0, sig: 1.0}", 2.5),
    "morse": ("D0*(exp(-2*alpha*(r-r0))-2*exp(-alpha*(r-r0)))", "{D0: 3.0, alpha: 2.0, r0: 1.0}", 2.5),
}


@pytest.mark.lammps
@requires_lammps
@pytest.mark.parametrize("name", sorted(LEPTON_SLITS))
def test_lammps_wall_lepton_slit_trajectories(tmp_path, name):
    expr, params, rc = LEPTON_SLITS[name]
    text = slit(f"w: {{style: lepton, units: box, energy: true, zlo: {{coord: EDGE, expression: '{expr}', "
                f"params: {params}, cutoff: {rc}}}, zhi: {{coord: EDGE, expression: '{expr}', params: {params}, "
                f"cutoff: {rc}}}}}\n")
    report = _validate(write(tmp_path, text))
    rows = {r.output: r for r in report.rows}
    assert rows["wall_force[w/zlo]"].status == "ok" and rows["pe"].max_rel <= 1e-9


@pytest.mark.lammps
@requires_lammps
def test_lammps_wall_lepton_with_pair_forces_compiled(tmp_path, monkeypatch):
    """An LJ gas (pair lj/cut) between wall/lepton faces, lj93 spelled out below and a
    4-parameter expression above (its parameters as an array), run by the compiled pair chunk with
    the generated forces (forced: WALLBATCH_NUMBA=1, WALLBATCH_LEPTON_COMPILED=always): LAMMPS's
    fix wall/lepton on the exported scene agrees on every output."""
    from wallbatch.engine import pair_compiled  # noqa: PLC0415

    monkeypatch.setenv("WALLBATCH_NUMBA", "1")
    monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "always")
    made: list = []  # the fused pair chunks of the run (their counters)
    real = pair_compiled.attach_pair_chunks
    monkeypatch.setattr(pair_compiled, "attach_pair_chunks", lambda *a: made.append(real(*a)) or made[-1])
    text = slit("w: {style: lepton, units: box, energy: true, "
                "zlo: {coord: EDGE, expression: 'eps*(2/15*(sig/r)^9-(sig/r)^3)', params: {eps: 1.0, sig: 1.0}, "
                "cutoff: 2.5}, zhi: {coord: EDGE, expression: 'a*(r-rc)^2 + b*exp(-r/l)', "
                "params: {a: 20.0, rc: 2.0, b: 3.0, l: 0.4}, cutoff: 2.0}}\n", steps=300, thermo=50, count=60,
                extra="pair: {style: lj/cut, epsilon: 1.0, sigma: 1.0, cutoff: 2.5}\n")
    text = text.replace("region: inner}", "region: inner, overlap: 1.0}")  # no two atoms closer than sigma
    report = _validate(write(tmp_path, text))
    rows = {r.output: r for r in report.rows}
    assert made and made[0] is not None and made[0].compiled_chunks > 0 and made[0].fallbacks == 0
    assert rows["wall_force[w/zhi]"].status == "ok" and rows["pe"].max_rel <= 1e-9


@pytest.mark.lammps
@requires_lammps
@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_lammps_wall_table_slit_trajectories(tmp_path, tabstyle):
    tab = lj93_tables(tmp_path, n=300)
    text = slit(f"t: {{style: table, tabstyle: {tabstyle}, N: 700, units: box, energy: true, "
                f"zlo: {{coord: EDGE, file: {tab.name}, keyword: LJ93, cutoff: 2.5}}, "
                f"zhi: {{coord: EDGE, file: {tab.name}, keyword: HARM, cutoff: 2.0}}}}\n")
    _validate(write(tmp_path, text))


# ------------------------------------------------------------------------------ wallbatch table


def test_cli_table_of_an_expression_matches_the_expression_wall(tmp_path):
    """`wallbatch table EXPR` writes E, F and FP = dF/dr (exact); a spline table of it reproduces
    the expression wall to the spline's accuracy, and a built-in style tabulates too."""
    from typer.testing import CliRunner  # noqa: PLC0415

    from wallbatch.cli import app  # noqa: PLC0415
    from wallbatch.styles.lepton import compile_expression  # noqa: PLC0415
    from wallbatch.styles.table import WallTable, read_table  # noqa: PLC0415

    out = tmp_path / "m.table"
    expr = "D0*(exp(-2*alpha*(r-r0))-2*exp(-alpha*(r-r0)))"
    runner = CliRunner()
    res = runner.invoke(app, ["table", expr, "-p", "D0=2", "-p", "alpha=1.5", "-p", "r0=1.2", "--lo", "0.2",
                              "--hi", "3.0", "-n", "800", "-k", "MORSE", "-o", str(out)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["table", "lj93", "-p", "epsilon=1", "-p", "sigma=1", "-p", "cutoff=2.5",
                              "--lo", "0.5", "--hi", "3.0", "-k", "LJ", "-o", str(out), "--append"])
    assert res.exit_code == 0, res.output
    d = read_table(out, "MORSE")
    a, al = 1.5, 1.5 * (d.r - 1.2)
    assert d.fplo == pytest.approx(2 * a * 2.0 * (-2 * a * np.exp(-2 * al) + a * np.exp(-al))[0], rel=1e-12)
    t = WallTable.build(d, "spline", 800)
    e0 = compile_expression(expr, ("D0", "alpha", "r0"))
    rs = np.linspace(0.3, 2.9, 777)
    e, f = t.lookup(rs)
    e_ref, f_ref = e0.energy_force(rs, {"D0": 2.0, "alpha": 1.5, "r0": 1.2})
    assert np.max(np.abs(e - e_ref)) < 1e-8 and np.max(np.abs(f - f_ref)) < 1e-7
    lj = read_table(out, "LJ")
    np.testing.assert_array_equal(lj.e, lj93(lj.r, LJ)[0])
    bad = runner.invoke(app, ["table", "colloid", "--lo", "1", "--hi", "2", "-o", str(tmp_path / "c.table")])
    assert bad.exit_code == 2 and "depends on the particle radius" in bad.output


def test_cli_table_append_refuses_a_keyword_the_file_already_has(tmp_path):
    """LAMMPS (and read_table) read the first section of a keyword: appending a second section of
    that keyword (a new epsilon, say) was silently never read. It is refused, naming the file
    and the line of the first section, and the file is left unchanged."""
    from typer.testing import CliRunner  # noqa: PLC0415

    from wallbatch.cli import app  # noqa: PLC0415
    from wallbatch.styles.table import read_table  # noqa: PLC0415

    out = tmp_path / "w.table"
    runner = CliRunner()
    args = ["table", "lj93", "-p", "sigma=1", "-p", "cutoff=2.5", "--lo", "0.5", "--hi", "3.0", "-n", "50",
            "-k", "LJ", "-o", str(out), "--append"]
    assert runner.invoke(app, [*args, "-p", "epsilon=1"]).exit_code == 0
    before = out.read_text()
    res = runner.invoke(app, [*args, "-p", "epsilon=2"])
    assert res.exit_code == 2
    assert f"{out}:3: the file already has a section 'LJ'" in res.output
    assert "choose another keyword (-k), or write a new file" in res.output
    assert out.read_text() == before
    res = runner.invoke(app, [*args[:-4], "LJ2", "-o", str(out), "--append", "-p", "epsilon=2"])
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(read_table(out, "LJ2").e, 2 * read_table(out, "LJ").e)


def test_cli_table_refuses_to_overwrite_and_a_table_short_of_the_cut_off(tmp_path):
    """`wallbatch table -o FILE` on an existing file replaced it silently (a section written before
    lost): refused unless --append or --force, naming -o; a built-in style tabulated only up to
    --hi below its cut-off wrote a table every wall/table of that cut-off refuses later: refused
    at once. Neither touches the file."""
    from typer.testing import CliRunner  # noqa: PLC0415

    from wallbatch.cli import app  # noqa: PLC0415
    from wallbatch.styles.table import read_table  # noqa: PLC0415

    out = tmp_path / "w.table"
    runner = CliRunner()
    args = ["table", "lj93", "-p", "epsilon=1", "-p", "sigma=1", "--lo", "0.5", "-n", "50", "-o", str(out)]
    assert runner.invoke(app, [*args, "-p", "cutoff=2.5", "--hi", "3", "-k", "A"]).exit_code == 0
    before = out.read_text()
    res = runner.invoke(app, [*args, "-p", "cutoff=2.5", "--hi", "3", "-k", "B"])
    assert res.exit_code == 2
    assert f"-o {out}: the file exists; add --append to add section B to it, or --force to replace it" in res.output
    assert out.read_text() == before
    short = runner.invoke(app, [*args, "-p", "cutoff=2.5", "--hi", "2", "-k", "C", "--append"])
    assert short.exit_code == 2
    assert "hi = 2 is below the wall's cut-off 2.5" in short.output and "give --hi 2.5 or more" in short.output
    assert out.read_text() == before
    res = runner.invoke(app, [*args, "-p", "cutoff=2.0", "--hi", "2", "-k", "B", "--force"])
    assert res.exit_code == 0, res.output
    assert read_table(out, "B").r[-1] == 2.0
    with pytest.raises(Exception, match="no table section 'A'"):
        read_table(out, "A")


def test_linear_expression_wall_constant_force_runs():
    """A wall E = g r (a constant force g towards the wall: gravity above a reflecting floor) runs
    (LAMMPS aborts on it, see test_lepton.py); every atom feels exactly -g, and etot changes only
    by the reflections' O(g d) mirror steps."""
    text = slit("w: {style: lepton, units: box, energy: true, zlo: {coord: EDGE, cutoff: 6.0, expression: 'g*r', "
                "params: {g: 0.5}}}\nfloor: {style: reflect, units: box, zlo: EDGE, zhi: EDGE}\n", steps=400)
    cfg = load_config_text(text)
    res = run_one(cfg)
    etot = res.data["etot"]
    assert np.max(np.abs(etot - etot[0])) < 2e-3 * abs(etot[0])
    # every atom is within the cut-off: the wall's vector is N g (side -1 times F = -g)
    np.testing.assert_allclose(res.data["wall_force"][:, 0], 200 * 0.5, rtol=1e-14)


@pytest.mark.slow
@pytest.mark.parametrize("thermo", [50, 1])
def test_compiled_lepton_equals_numpy_bit_for_bit(monkeypatch, thermo):
    """The compiled path runs wall/lepton faces with the kernel generated from the expression,
    inlined like a built-in style: the trajectory equals the NumPy engine's bit for bit; sampled
    every step, the kernel records the outputs itself (E(r) - E(rc) generated from the expression,
    force on the wall, virial) and every output equals NumPy's bit for bit too."""
    face = "{coord: EDGE, cutoff: 2.5, expression: 'eps*(2/15*(sig/r)^9-(sig/r)^3)', params: {eps: 1.0, sig: 1.0}}"
    harm = "{coord: EDGE, cutoff: 1.5, expression: 'k*(r-rc)^2', params: {k: 30.0, rc: 1.5}}"
    text = slit(f"w: {{style: lepton, units: box, energy: true, virial: true, zlo: {face}, zhi: {harm}}}\n",
                steps=300, thermo=thermo).replace("etot]", "etot, press]")
    case = build_case(load_config_text(text))
    (compiled, fast), (numpy_res, none) = lepton_both_ways(monkeypatch, [case])
    assert none is None and fast is not None and fast.compiled_chunks > 0 and fast.fallbacks == 0
    assert fast.sampled_calls > 0  # the samples come from the kernel
    assert numpy_res[0].status == "ok" and np.all(numpy_res[0].data["wall_force"][1:] != 0.0)
    assert np.all(numpy_res[0].data["wall_energy"][1:] != 0.0)
    assert_same_results(numpy_res, compiled)  # every output, bit for bit


# wall/lepton faces with 4 and 5 parameters (their parameters as an array) and one of 2 (p0, p1)
LEPTON_FOUR = ("{coord: EDGE, cutoff: 2.0, expression: 'a*(r-rc)^2 + b*exp(-r/l)', "
               "params: {a: 20.0, rc: 2.0, b: 3.0, l: 0.4}}")
LEPTON_FIVE = ("{coord: EDGE, cutoff: 1.5, expression: 'k*(r-c)^2*(1+q*r) + s*exp(-r/w)', "
               "params: {k: 30.0, c: 1.5, q: 0.2, s: 1.0, w: 0.3}}")
LEPTON_TWO = "{coord: EDGE, cutoff: 1.0, expression: 'k*(r-rc)^2', params: {k: 5.0, rc: 1.0}}"
LEPTON_ARRAY_WALLS = (f"w: {{style: lepton, units: box, energy: true, zlo: {LEPTON_FOUR}, zhi: {LEPTON_FIVE}}}\n"
                      f"h: {{style: lepton, units: box, energy: true, zlo: {LEPTON_TWO}}}\n")


@pytest.mark.slow
def test_compiled_lepton_sweep_sampled_every_step_equals_numpy(tmp_path, monkeypatch):
    """A 3-case sweep of expression parameters (k of a 2-parameter expression, p0 and p1, and b of a
    4-parameter expression whose parameters go as an array), sampled every step: the kernel
    records every sample (energies from the generated E(r) - E(rc)) and the trajectories and
    outputs equal the NumPy engine's bit for bit, differing between the cases. (The walls of
    test_compiled_lepton_with_more_than_three_parameters_equals_numpy: one kernel for both.)"""
    text = slit(LEPTON_ARRAY_WALLS.replace("energy: true", "energy: true, virial: true"), steps=200, thermo=1,
                extra="sweep:\n  zip:\n    dim: strength\n    params:\n"
                      "      k: {path: walls.h.zlo.params.k, values: [2.0, 5.0, 8.0]}\n"
                      "      b: {path: walls.w.zlo.params.b, values: [1.0, 3.0, 5.0]}\n"
                ).replace("etot]", "etot, press]")
    plan = load_plan(write(tmp_path, text))
    cases = [build_case(c.config, c.seed_key) for c in plan.cases]
    assert len(cases) == 3 and len({structure_key(c) for c in cases}) == 1
    (compiled, fast), (numpy_res, none) = lepton_both_ways(monkeypatch, cases)
    assert none is None and fast is not None and fast.fallbacks == 0 and fast.sampled_calls > 0
    assert fast.compiled_chunks == 200  # every sample from the kernel
    for n in numpy_res:  # every face acts (h's short cut-off: at some steps); wall_energy per fix
        assert n.status == "ok" and np.all(n.data["wall_force"][1:, :2] != 0.0)
        assert np.any(n.data["wall_force"][1:, 2] != 0.0) and np.any(n.data["wall_energy"][1:, 1] != 0.0)
    assert_same_results(numpy_res, compiled)
    assert len({float(r.data["wall_energy"][1:].sum()) for r in numpy_res}) == 3


@pytest.fixture
def lepton_policy(tmp_path, monkeypatch):
    """(engine.compiled, the generated force of k*(r-rc)^2 as a kernel's `extra`) with the wall/lepton
    policy fresh: its own cache folder (no markers), no kernel run yet, WALLBATCH_LEPTON_COMPILED unset."""
    fast = pytest.importorskip("wallbatch.engine.compiled")
    from wallbatch.styles.lepton import compile_expression, force_source  # noqa: PLC0415

    monkeypatch.setenv("WALLBATCH_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("WALLBATCH_LEPTON_COMPILED", raising=False)
    monkeypatch.setattr(fast, "_LEPTON_RUN", set())
    return fast, (force_source(compile_expression("k*(r-rc)^2", ("k", "rc"))),)


def test_lepton_auto_policy_picks_the_faster_path_for_this_run(lepton_policy, monkeypatch):
    """WALLBATCH_LEPTON_COMPILED=auto: a batch runs compiled when the cost model (steps, atoms over
    its cases, samples; the kernel's load or compile) expects it to take less time in this run
    than the NumPy path, decided once per batch (every chunk of a run gets the first answer);
    always / never decide alone."""
    from types import SimpleNamespace  # noqa: PLC0415

    fast, extra = lepton_policy

    def state(cases: int, atoms: int, steps: int) -> SimpleNamespace:
        return SimpleNamespace(end_step=steps, step=np.zeros(cases, np.int64), x=np.zeros((cases, atoms, 3)))

    def wanted(cases: int, atoms: int, steps: int, samples: int) -> bool:
        return fast.lepton_compiled_wanted(state(cases, atoms, steps), extra, lambda: samples)

    # the model: NumPy per step, atom-step and sample; compiled per atom-step after its start
    numpy_s, compiled_s = fast.lepton_seconds(6000, 1000, 6000, "cached")
    assert numpy_s == pytest.approx(6000 * (fast.LEPTON_NUMPY_STEP_S + 1000 * fast.LEPTON_NUMPY_ATOM_STEP_S)
                                    + 6000 * (fast.LEPTON_NUMPY_SAMPLE_S + 1000 * fast.LEPTON_NUMPY_SAMPLE_ATOM_S))
    assert compiled_s == pytest.approx(fast.LEPTON_LOAD_S + 6e6 * fast.LEPTON_COMPILED_ATOM_STEP_S)
    # not compiled yet: only where the compile pays for itself in this run
    assert not wanted(1, 1000, 6000, 6000)
    assert not wanted(1, 100_000, 10_000, 10)
    assert wanted(1, 1_000_000, 10_000, 10)
    early = state(1, 1000, 6000)
    assert not fast.lepton_compiled_wanted(early, extra, lambda: 6000)
    # on disk (compiled by an earlier process): the ~0.5 s load pays for itself from about 0.5 s of NumPy work
    fast._compiled_marker(extra).write_text("")
    assert wanted(1, 1000, 6000, 6000)  # the every-step panel's lepton row (thermo 1)
    assert wanted(1, 1000, 2000, 2000)  # sampled every step: the samples tip it
    assert not wanted(1, 1000, 2000, 20)  # the same run sampled every 100 steps: NumPy is quicker
    assert wanted(30, 1000, 2000, 20)  # thirty such cases in one batch
    assert not fast.lepton_compiled_wanted(early, extra, lambda: 6000)  # a batch keeps its first answer
    # already run in this process: no start-up cost left, even a short run goes compiled
    fast._mark_compiled(extra)
    assert wanted(1, 100, 100, 1) and wanted(1, 1000, 2000, 20)
    monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "never")
    assert not wanted(1, 1_000_000, 10_000, 10)
    monkeypatch.setenv("WALLBATCH_LEPTON_COMPILED", "always")
    assert wanted(1, 10, 10, 1)


def test_lepton_auto_policy_with_pair_forces_has_its_own_kernel_and_model(lepton_policy):
    """With pair lj/cut the fused pair chunk runs the wall/lepton faces (kind "pair"): its kernel
    is another compile with its own marker, and the model counts only what differs between the
    paths (both run the compiled pair forces): NumPy's walls and integration per step and
    atom-step against nothing, plus the kernel's start."""
    from types import SimpleNamespace  # noqa: PLC0415

    fast, extra = lepton_policy

    def wanted(kind: str, atoms: int, steps: int) -> bool:
        st = SimpleNamespace(end_step=steps, step=np.zeros(1, np.int64), x=np.zeros((1, atoms, 3)))
        return fast.lepton_compiled_wanted(st, extra, lambda: 10, kind)

    numpy_s, compiled_s = fast.lepton_seconds(5000, 4000, 0, "new", "pair")
    assert numpy_s == pytest.approx(5000 * (fast.LEPTON_PAIR_NUMPY_STEP_S + 4000 * fast.LEPTON_PAIR_NUMPY_ATOM_STEP_S))
    assert compiled_s == pytest.approx(fast.LEPTON_PAIR_COMPILE_S)
    assert not wanted("pair", 4000, 20_000)  # ~4.5 s of NumPy walls: not worth a first compile
    assert wanted("pair", 4000, 200_000)
    fast._mark_compiled(extra)  # the flat chunk's kernel has run: not the pair chunk's
    assert not fast._compiled_marker(extra, "pair").exists() and not wanted("pair", 4000, 20_000)
    fast._mark_compiled(extra, "pair")
    assert fast._compiled_marker(extra, "pair").exists() and wanted("pair", 4000, 20_000) and wanted("pair", 100, 10)


@pytest.mark.slow
def test_lepton_chunk_kernel_is_loaded_from_disk_by_a_second_process(tmp_path):
    """The chunk kernel generated for an expression wall is compiled by the first process and
    loaded from numba's on-disk cache by the next (no compile), with the same trajectory bits."""
    import json  # noqa: PLC0415
    import os  # noqa: PLC0415
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415

    text = slit("w: {style: lepton, units: box, energy: true, zlo: {coord: EDGE, cutoff: 1.5, expression: "
                "'k*(r-rc)^2', params: {k: 30.0, rc: 1.5}}}\n" + TOP, steps=200)
    probe = ("import json, sys\n"
             "from wallbatch.config.models import load_config_text\n"
             "from wallbatch.engine import compiled\n"
             "from wallbatch.engine.engine import Engine\n"
             "from wallbatch.scene.build import build_case\n"
             "engine = Engine([build_case(load_config_text(sys.stdin.read()))])\n"
             "res = engine.run()[0]\n"
             "assert res.status == 'ok' and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0\n"
             "kernel = engine.fast.kernel\n"
             "print(json.dumps({'hits': sum(kernel.stats.cache_hits.values()),\n"
             "                  'misses': sum(kernel.stats.cache_misses.values()),\n"
             "                  'etot': res.data['etot'].tolist()}))\n")
    env = {**os.environ, "WALLBATCH_CACHE_DIR": str(tmp_path), "WALLBATCH_LEPTON_COMPILED": "always",
           "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    runs = [json.loads(subprocess.run([sys.executable, "-c", probe], input=text, capture_output=True, text=True,
                                      env=env, timeout=1800, check=True).stdout) for _ in range(2)]
    assert (runs[0]["hits"], runs[0]["misses"]) == (0, 1)  # compiled (and written to disk)
    assert (runs[1]["hits"], runs[1]["misses"]) == (1, 0)  # loaded
    assert runs[0]["etot"] == runs[1]["etot"]
    assert list((tmp_path / "kernels").glob("lepton_chunk_*.compiled"))


@pytest.mark.slow
@pytest.mark.parametrize("walls", [
    # both faces of one fix: a linear table below, a spline table above
    "a: {style: table, tabstyle: linear, N: 700, units: box, energy: true, "
    "zlo: {coord: EDGE, file: walls.table, keyword: LJ93, cutoff: 2.5}, "
    "zhi: {coord: EDGE, file: walls.table, keyword: HARM, cutoff: 2.0}}\n"
    "b: {style: table, tabstyle: spline, N: 500, units: box, energy: true, "
    "zhi: {coord: EDGE, file: walls.table, keyword: HARM, cutoff: 1.5}}\n",
    # two fixes, other tables and cut-offs, the same file section at two resolutions
    "a: {style: table, tabstyle: spline, N: 90, units: box, energy: true, "
    "zlo: {coord: EDGE, file: walls.table, keyword: HARM, cutoff: 1.2}}\n"
    "b: {style: table, tabstyle: linear, N: 3000, units: box, "
    "zhi: {coord: EDGE, file: walls.table, keyword: LJ93, cutoff: 3.0}}\n",
])
def test_compiled_tables_equal_numpy_bit_for_bit(tmp_path, monkeypatch, walls):
    """wall/table faces run in the built-in scene kernel at default settings, their tables
    passed as data (no per-table compile): a sweep over the cut-off in one batch gives the NumPy
    engine's trajectories and outputs bit for bit (linear and spline, lo and hi faces, several
    tables in one kernel)."""
    from wallbatch.engine import compiled as fast_mod  # noqa: PLC0415

    monkeypatch.delenv("WALLBATCH_LEPTON_COMPILED", raising=False)
    lj93_tables(tmp_path, n=300)
    path = "walls.a.zlo.cutoff"
    text = slit(walls, steps=300, extra=f"sweep:\n  product:\n    rc: {{path: {path}, values: [1.0, 1.1, 1.2]}}\n")
    plan = load_plan(write(tmp_path, text))
    cases = [build_case(c.config, c.seed_key) for c in plan.cases]
    assert len({structure_key(c) for c in cases}) == 1
    numpy_res, compiled, engine = run_numpy_and_compiled(monkeypatch, cases)
    fast = engine.fast
    assert fast is not None and fast.compiled_chunks > 0 and fast.fallbacks == 0
    assert fast.sampled_calls > 0  # the outputs too are the kernel's (its table energies)
    assert fast_mod._lepton_extra(engine.compiled_plan()) == ()  # nothing generated per table
    assert all(n.status == "ok" and np.any(n.data["wall_force"][1:] != 0.0) for n in numpy_res)
    assert_same_results(numpy_res, compiled)  # every output, bit for bit
    assert len({float(r.data["wall_energy"][1:].sum()) for r in numpy_res}) == 3


@pytest.mark.slow
@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_compiled_table_face_over_blocks_groups_and_threads(tmp_path, monkeypatch, tabstyle):
    """The compiled table face visits only the group atoms within the cut-off (marks packed 64
    to a word) and records the outputs itself: 613 atoms (blocks of 256 and a last one of 101, no multiple of 8 or 64), walls
    on one of two groups (the other held by a second table fix), dense near the walls: trajectories
    and outputs equal the NumPy engine's bit for bit, and the same with two threads splitting the
    atoms."""
    from wallbatch.engine import compiled as compiled_mod  # noqa: PLC0415
    from wallbatch.engine import threads  # noqa: PLC0415

    lj93_tables(tmp_path, n=300)
    text = textwrap.dedent(f"""\
        name: blocks
        units: lj
        seed: 11
        box: {{lo: [0, 0, 0], hi: [8, 8, 5], boundary: [p, p, f]}}
        regions:
          inner: {{style: block, lo: [0, 0, 0.7], hi: [8, 8, 4.3], units: box}}
        atoms:
          - {{group: a, create: {{random: {{count: 409, region: inner}}}}, mass: 1.0, velocity: {{temperature: 2.0}}}}
          - {{group: b, create: {{random: {{count: 204, region: inner}}}}, mass: 2.0, velocity: {{temperature: 1.0}}}}
        walls:
          t: {{style: table, tabstyle: {tabstyle}, N: 800, units: box, energy: true, virial: true, group: a,
              zlo: {{coord: EDGE, file: walls.table, keyword: LJ93, cutoff: 2.5}},
              zhi: {{coord: EDGE, file: walls.table, keyword: HARM, cutoff: 2.0}}}}
          u: {{style: table, tabstyle: {tabstyle}, N: 800, units: box, group: b,
              zlo: {{coord: EDGE, file: walls.table, keyword: HARM, cutoff: 2.0}},
              zhi: {{coord: EDGE, file: walls.table, keyword: HARM, cutoff: 2.0}}}}
        run: {{steps: 300, thermo: 30}}
        output: {{thermo: [step, temp, ke, pe, etot, press]}}
        """)
    cases = [build_case(load_config(write(tmp_path, text)))]
    monkeypatch.setenv("WALLBATCH_THREADS", "1")
    numpy_res, compiled, engine = run_numpy_and_compiled(monkeypatch, cases)
    assert engine.fast is not None and engine.fast.compiled_chunks > 0 and engine.fast.fallbacks == 0
    assert engine.fast.sampled_calls > 0  # energies, wall forces: recorded inside the kernel
    assert numpy_res[0].status == "ok" and np.all(numpy_res[0].data["wall_force"][1:] != 0.0)
    assert_same_results(numpy_res, compiled)
    monkeypatch.setenv("WALLBATCH_THREADS", "2")
    monkeypatch.setattr(threads, "MIN_WORK", 1)
    monkeypatch.setattr(compiled_mod, "SPLIT_SAMPLE_STEPS", 1)  # thermo 30: split over atoms all the same
    before = threads.splits["atoms"]
    _, two, _ = run_numpy_and_compiled(monkeypatch, cases)
    assert threads.splits["atoms"] > before
    assert_same_results(numpy_res, two)


@pytest.mark.slow
def test_compiled_lepton_with_more_than_three_parameters_equals_numpy(tmp_path, monkeypatch):
    """Expressions with more than 3 parameters run compiled with their parameters as a per-face
    row of an array (swept per case), beside an expression of 2 parameters (p0, p1): the
    trajectories and outputs equal the NumPy engine's bit for bit, and differ between cases."""
    text = slit(LEPTON_ARRAY_WALLS, steps=300,
                extra="sweep:\n  product:\n    b: {path: walls.w.zlo.params.b, values: [1.0, 4.0]}\n")
    plan = load_plan(write(tmp_path, text))
    cases = [build_case(c.config, c.seed_key) for c in plan.cases]
    (compiled, fast), (numpy_res, none) = lepton_both_ways(monkeypatch, cases)
    assert none is None and fast is not None and fast.compiled_chunks > 0 and fast.fallbacks == 0
    for c, n in zip(compiled, numpy_res):
        assert c.status == n.status == "ok", (c.error, n.error)
        assert np.all(n.data["wall_force"][1:, :2] != 0.0) and np.any(n.data["wall_force"][1:, 2] != 0.0)
        for key in ("etot", "wall_energy", "wall_force", "temp"):
            np.testing.assert_array_equal(c.data[key], n.data[key])
    assert not np.array_equal(numpy_res[0].data["wall_energy"], numpy_res[1].data["wall_energy"])
