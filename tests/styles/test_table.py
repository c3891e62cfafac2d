"""Tabulated walls (styles/table.py): file reader, LAMMPS interpolation, shift, convergence."""

from __future__ import annotations

import numpy as np
import pytest

from lammps_oracle import requires_lammps
from wallbatch.styles import STYLES
from wallbatch.styles.table import (
    TableError,
    WallTable,
    read_table,
    spline_coefficients,
    spline_eval,
    tabulate,
    write_table,
)


def _builtin(name: str):
    """A registry style as energy_force(r, p) -> (E, F) on a parameter mapping."""
    def energy_force(r, p):
        return STYLES[name].energy_force(r, p)

    energy_force.__name__ = name
    return energy_force


harmonic = _builtin("harmonic")
lj93 = _builtin("lj93")

LJ = {"epsilon": 1.0, "sigma": 1.0}


def _lj93_table(tmp_path, n=200, lo=0.5, hi=4.0, fp=None, name="t.table", keyword="LJ93"):
    r, e, f = tabulate(lambda r: lj93(r, LJ), lo, hi, n)
    path = tmp_path / name
    write_table(path, keyword, r, e, f, fp=fp, comment="lj93 eps=1 sigma=1")
    return path


def test_read_round_trip(tmp_path):
    r, e, f = tabulate(lambda r: harmonic(r, {"epsilon": 2.0, "cutoff": 3.0}), 0.25, 3.0, 12)
    path = tmp_path / "h.table"
    write_table(path, "A", r, e, f)
    write_table(path, "B", r, 2 * e, 2 * f, fp=(-4.0, -4.0), append=True)
    a, b = read_table(path, "A"), read_table(path, "B")
    np.testing.assert_array_equal(a.r, r)
    np.testing.assert_array_equal(a.e, e)
    np.testing.assert_array_equal(b.f, 2 * f)
    assert (a.fplo, b.fplo, b.fphi) == (None, -4.0, -4.0)
    assert b.line > a.line > 0


@pytest.mark.parametrize(
    "text,needle",
    [
        ("X\nN 2\n\n1 1.0 0 0\n2 2.0 0 0\n", ":1: no table section 'A'"),
        ("A\nN two\n", ":2: bad table parameter line"),
        ("A\nN 3 XY 1\n", ":2: unknown table parameter 'XY'"),
        ("A\nN 3\n\n1 1.0 0 0\n2 2.0 zero 0\n", ":5: bad table line '2 2.0 zero 0'"),
        ("A\nN 3\n\n1 1.0 0 0\n2 2.0 0 0\n", ":1: section 'A' ends after 2 of 3 lines"),
        ("A\nN 2\n\n1 2.0 0 0\n2 1.0 0 0\n", ":1: section 'A': r must increase"),
    ],
)
def test_reader_errors_name_file_and_line(tmp_path, text, needle):
    path = tmp_path / "bad.table"
    path.write_text(text)
    with pytest.raises(TableError) as err:
        read_table(path, "A")
    msg = str(err.value)
    if needle.startswith(":1: no table"):
        assert msg == f"{path}: no table section 'A': give one of X"  # (and the error is the keyword's)
        assert err.value.key == "keyword"
    else:
        assert f"{path}{needle}" in msg


def test_missing_file():
    with pytest.raises(TableError, match="cannot read table file"):
        read_table("/nonexistent/x.table", "A")


def test_clamped_spline_reproduces_a_cubic():
    """A clamped cubic spline through a cubic with exact end slopes is the cubic."""
    x = np.linspace(0.5, 3.0, 9)
    y = 2.0 * x**3 - x**2 + 0.5 * x - 1.0
    dy = lambda t: 6.0 * t**2 - 2.0 * t + 0.5  # noqa: E731
    y2 = spline_coefficients(x, y, dy(x[0]), dy(x[-1]))
    np.testing.assert_allclose(y2, 12.0 * x - 2.0, rtol=1e-12, atol=1e-11)
    xs = np.linspace(0.5, 3.0, 101)
    np.testing.assert_allclose(spline_eval(x, y, y2, xs), 2.0 * xs**3 - xs**2 + 0.5 * xs - 1.0, rtol=1e-13)


def test_table_of_a_cubic_is_exact(tmp_path):
    """E a cubic, F = -E' with FP = dF/dr at the ends: resampling and spline lookups are exact;
    linear lookups have the interpolation error h^2/8 max|E''|."""
    r = np.linspace(1.0, 3.0, 11)
    e = (r - 3.0) ** 3
    f = -3.0 * (r - 3.0) ** 2
    path = tmp_path / "c.table"
    write_table(path, "C", r, e, f, fp=(-6.0 * (1.0 - 3.0), 0.0))
    t = WallTable.build(read_table(path, "C"), "spline", 37)
    xs = np.linspace(1.0, 3.0, 301)
    es, fs = t.lookup(xs)
    np.testing.assert_allclose(es, (xs - 3.0) ** 3, atol=1e-13)
    np.testing.assert_allclose(fs, -3.0 * (xs - 3.0) ** 2, atol=1e-13)
    el, _ = t.lookup(xs, "linear")
    h = t.delta
    assert np.max(np.abs(el - (xs - 3.0) ** 3)) <= h * h / 8 * 12.0 * (1 + 1e-9)
    assert np.max(np.abs(el - (xs - 3.0) ** 3)) > h * h / 8 * 12.0 * 0.5  # the bound is tight


@pytest.mark.parametrize("tabstyle,order", [("linear", 2), ("spline", 4)])
def test_fine_table_converges_to_the_analytic_wall(tmp_path, tabstyle, order):
    """Error of E and F against lj93 falls as h^2 (linear) or h^4 (spline)."""
    errs = []
    xs = np.linspace(0.8, 2.5, 997)
    e0, f0 = lj93(xs, LJ)
    for n in (400, 800, 1600):
        dfdr = lambda r: -12.0 * r**-11 + 12.0 * r**-5  # noqa: E731 - d/dr of lj93's F
        path = _lj93_table(tmp_path, n=n, lo=0.75, hi=2.5, fp=(dfdr(0.75), dfdr(2.5)))
        t = WallTable.build(read_table(path, "LJ93"), tabstyle, n)
        e, f = t.lookup(xs)
        errs.append(max(np.max(np.abs(e - e0)), np.max(np.abs(f - f0) / 10.0)))
    rate = np.log2(errs[0] / errs[1]), np.log2(errs[1] / errs[2])
    assert errs[-1] < (1e-4 if order == 2 else 1e-9)
    assert min(rate) > order - 0.3, (errs, rate)


def test_offset_is_a_linear_lookup_also_for_spline(tmp_path):
    path = _lj93_table(tmp_path, n=30)
    d = read_table(path, "LJ93")
    t = WallTable.build(d, "spline", 9)  # coarse: linear and spline differ a lot at rc
    rc = 2.3
    e_lin = t.lookup(rc, "linear")[0]
    e_spl = t.lookup(rc, "spline")[0]
    assert abs(e_lin - e_spl) > 1e-3
    assert t.offset(rc) == e_lin
    e, _ = t.shifted_energy_force(np.array([rc]), rc)
    assert e[0] == pytest.approx(e_spl - e_lin, abs=1e-15)


def test_outside_table_is_an_error(tmp_path):
    t = WallTable.build(read_table(_lj93_table(tmp_path), "LJ93"), "linear", 100)
    with pytest.raises(TableError, match="outside the table"):
        t.lookup(np.array([1.0, 0.4]))
    with pytest.raises(TableError, match="linear' or 'spline"):
        WallTable.build(read_table(_lj93_table(tmp_path), "LJ93"), "cubic", 100)


@pytest.mark.lammps
@requires_lammps
@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
@pytest.mark.parametrize("n_lammps", [9, 73, 500])
@pytest.mark.parametrize("fp", [None, (1.0, -0.5)])
def test_lammps_wall_table_lookups(tmp_path, tabstyle, n_lammps, fp):
    """Per-atom forces, the fix's energy (shifted by a linear lookup at rc) and vector equal
    LAMMPS's wall/table, for tables with and without FP, resampled coarser and finer."""
    from lammps_walls import probe_wall  # noqa: PLC0415

    path = _lj93_table(tmp_path, n=200, fp=fp)
    t = WallTable.build(read_table(path, "LJ93"), tabstyle, n_lammps)
    rc = 2.5
    r = np.random.default_rng(n_lammps).uniform(0.55, 2.7, 60)
    out = probe_wall(f"wall/table {tabstyle} {n_lammps} zlo -5.0 {path} LJ93 {rc!r} units box", r)
    inside = r < rc
    e, f = t.shifted_energy_force(np.where(inside, r, rc), rc)
    e, f = np.where(inside, e, 0.0), np.where(inside, f, 0.0)
    scale = np.max(np.abs(f))
    np.testing.assert_allclose(out["f"][:, 2], f, rtol=1e-13, atol=1e-14 * scale)
    assert out["energy"] == pytest.approx(e.sum(), rel=1e-13, abs=1e-14 * np.max(np.abs(e)))
    assert out["vector"][0] == pytest.approx(-f.sum(), rel=1e-13, abs=1e-14 * scale)


@pytest.mark.lammps
@requires_lammps
def test_lammps_refuses_what_we_refuse(tmp_path):
    """LAMMPS errors for an atom nearer than the table's first r and for rc beyond its last."""
    from lammps_walls import probe_wall  # noqa: PLC0415

    path = _lj93_table(tmp_path)
    with pytest.raises(Exception, match="table inner cutoff"):
        probe_wall(f"wall/table linear 50 zlo -5.0 {path} LJ93 2.5 units box", np.array([0.4]))
    with pytest.raises(Exception, match="larger than table outer cutoff"):
        probe_wall(f"wall/table linear 50 zlo -5.0 {path} LJ93 4.5 units box", np.array([1.0]))


@pytest.mark.lammps
@requires_lammps
@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_lammps_extrapolates_the_first_interval_as_we_do(tmp_path, tabstyle):
    """Below the table's first distance lo and above lo - delta, LAMMPS looks up the first
    interval (its index truncates to 0) instead of stopping: its per-atom forces and the fix's
    energy equal WallTable.lookup's there (lj93 from lo = 0.5, N = 50: delta = 3.5/49); at
    (r - lo)/delta just below -1 both refuse."""
    from lammps_walls import probe_wall  # noqa: PLC0415

    path = _lj93_table(tmp_path)
    t = WallTable.build(read_table(path, "LJ93"), tabstyle, 50)
    r = np.array([t.lo - 0.999 * t.delta, t.lo - 0.5 * t.delta, t.lo - 1e-9, t.lo, t.lo + 0.3 * t.delta])
    assert t.below(r).sum() == 0 and np.all(t.below(t.lo - 1.001 * t.delta))
    got = probe_wall(f"wall/table {tabstyle} 50 zlo -5.0 {path} LJ93 2.5 units box", r)
    e, f = t.lookup(r)
    np.testing.assert_allclose(got["f"][:, 2], f, rtol=1e-12)
    assert got["energy"] == pytest.approx(float(np.sum(e - t.offset(2.5))), rel=1e-12)
    assert f[0] > f[1] > f[3]  # the extrapolated force keeps rising towards the wall
    with pytest.raises(Exception, match="table inner cutoff"):
        probe_wall(f"wall/table {tabstyle} 50 zlo -5.0 {path} LJ93 2.5 units box",
                   np.array([t.lo - 1.001 * t.delta]))
    with pytest.raises(TableError, match="outside the table"):
        t.lookup(np.array([t.lo - 1.001 * t.delta]))


@pytest.mark.parametrize("tabstyle", ["linear", "spline"])
def test_kernel_rows_jitted_lookup_is_the_numpy_lookup_bit_for_bit(tabstyle):
    """WallTable.kernel_rows: the table as the compiled path's data (grid, F, dF or F2, E, dE or
    E2, dE), looked up by the same linear_lookup / spline_lookup jitted, equals lookup()'s force
    and energy, and offset()'s linear energy at the cut-off, bit for bit over the whole table
    (random points, grid points, the last point)."""
    from numba import njit  # noqa: PLC0415

    from wallbatch.styles.table import TableData, WallTable, linear_lookup, spline_lookup  # noqa: PLC0415

    lj93 = STYLES["lj93"]
    p = {"epsilon": 1.3, "sigma": 0.9, "cutoff": 3.0}
    r = np.linspace(0.4, 3.0, 257)
    e, f = lj93.energy_force(r, p)
    table = WallTable.build(TableData("LJ", r, e, f, None, None), tabstyle, 500)
    rows = table.kernel_rows()
    assert rows.shape == (6, 500) and rows.flags.c_contiguous
    lin, spl = njit(error_model="numpy")(linear_lookup), njit(error_model="numpy")(spline_lookup)
    rs = np.concatenate([np.random.default_rng(5).uniform(0.4, 3.0, 400), table.r, [3.0]])
    want_e, want_f = table.lookup(rs)
    idx = [min(int((x - table.lo) * table.invdelta), 498) for x in rs]
    for want, y, d in ((want_f, 1, 2), (want_e, 3, 4)):
        if tabstyle == "linear":
            got = [lin(x, i, rows[0], rows[y], rows[d], table.invdelta) for x, i in zip(rs, idx)]
        else:
            got = [spl(x, i, rows[0], rows[y], rows[d], table.invdelta, table.deltasq6) for x, i in zip(rs, idx)]
        np.testing.assert_array_equal(np.array(got), want)
        assert np.any(want != 0.0)
    offsets = [lin(x, i, rows[0], rows[3], rows[5], table.invdelta) for x, i in zip(rs, idx)]
    assert offsets == [table.offset(x) for x in rs]


def test_table_sizes_and_keywords_are_checked_before_memory_or_the_file(tmp_path):
    """N or -n beyond 10,000,000 points is refused with the limit (it was a MemoryError: "unexpected
    ... please report"); a keyword of several words or none, which LAMMPS could not read back, is
    refused; a wall not finite at lo is named without NumPy's overflow warning."""
    import warnings

    from wallbatch.config.models import load_config_text
    from wallbatch.config.source import ConfigError
    from wallbatch.styles.table import MAX_TABLE_POINTS, TableError, write_source_table

    lj = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5}
    out = tmp_path / "w.table"
    with pytest.raises(TableError, match="n = 10,000,001: a table has at most 10,000,000 points"):
        write_source_table(out, "lj93", lj, 0.5, 3.0, MAX_TABLE_POINTS + 1, "LJ")
    for bad in ("A B", "", "#x"):
        with pytest.raises(TableError, match="a section keyword is one word"):
            write_source_table(out, "lj93", lj, 0.5, 3.0, 100, bad)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(TableError, match=r"'lj93' is not finite at r = 1e-300: choose a larger lo"):
            write_source_table(out, "lj93", lj, 1e-300, 3.0, 100, "LJ")
    write_source_table(out, "lj93", lj, 0.5, 3.0, 100, "LJ")
    head = ("box: {lo: [0,0,0], hi: [5,5,8], boundary: [p,p,f]}\n"
            "atoms: [{group: g, mass: 1, create: {positions: [[2,2,2]]}}]\n")
    for walls in (f"walls: {{w: {{style: table, units: box, tabstyle: spline, N: 10000001, "
                  f"zlo: {{coord: EDGE, file: {out}, keyword: LJ, cutoff: 2.5}}}}}}\n",
                  f"walls: {{w: {{fix: 'fix w all wall/table spline 10000001 zlo EDGE {out} LJ 2.5 units box'}}}}\n"):
        with pytest.raises(ConfigError) as err:
            load_config_text(head + walls + "run: {steps: 1}\n")
        assert "10000000" in err.value.problems[0].replace(",", ""), err.value.problems
