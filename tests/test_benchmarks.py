"""benchmarks/suite.py without timing anything: every row of the speed issue is registered with a
target that can fail, the scenes build and export to LAMMPS, and the table and README section are
written as documented. No timing assertions (the numbers live in benchmarks/results.md)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from wallbatch.scene.case import Case

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"

# The rows of issue 15's table and targets (plus issue 13 item 6 and issue 19's lepton row), each
# at the sizes the issue names.
REQUIRED = [
    "sweep27",
    *(f"gas-{w}-{n}" for w in ("lj93", "reflect", "harmonic", "colloid") for n in (1000, 10000, 100000)),
    "dtreset-10000",
    *(f"{k}-{n}" for k in ("ellipsoids-ees", "region-sphere", "region-cylinder", "region-ees", "flow-gas",
                           "thermostat-langevin", "thermostat-nvt", "thermostat-berendsen", "2d", "table",
                           "stochastic") for n in (1000, 10000)),
    "flow-lj-4000", "ljcut-4000", "ljcut-32000", "ljcut-100000",
    "every-step-100cases", "every-step-1case",
    "end-to-end-small", "startup-100", "first-run-compile", "jobs2-64cases", "threads-1e6", "memory-10k-cases",
    "lepton-vs-builtin",
]


@pytest.fixture(scope="module")
def suite():
    sys.path.insert(0, str(BENCH))
    try:
        spec = importlib.util.spec_from_file_location("suite", BENCH / "suite.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules["suite"] = mod
        spec.loader.exec_module(mod)
        yield mod
    finally:
        sys.path.remove(str(BENCH))


def test_every_issue_row_is_registered_with_a_function_and_a_target_that_can_fail(suite):
    missing = [k for k in REQUIRED if k not in suite.ROWS]
    assert not missing, missing
    assert len(set(suite.ROWS)) == len(suite.ROWS) >= len(REQUIRED)
    low, high = {"value": 0.0, "mb": 0.0}, {"value": 1e6, "mb": 1e6}
    for name, row in suite.ROWS.items():
        assert callable(row.fn), name
        assert row.target.text and row.source, name
        # a target met by every value is a defect: one of 0 and 1e6 must fail it
        assert row.target.check(low) != row.target.check(high), name


def test_table_has_every_column_and_says_why_a_row_is_not_applicable(suite):
    def passing(row):  # a value that meets the row's target (0 or 1e6, by the first test)
        return 1e6 if row.target.check({"value": 1e6, "mb": 0.0}) else 0.0

    fake = {k: {"scene": k, "N": 1000, "steps": 10, "wb": "1.00 s", "lmp": "2.00 s", "ratio": 2.0,
                "value": passing(row), "mb": 0.0} for k, row in suite.ROWS.items()}
    fake["ljcut-4000"] = {"scene": "x", "N": None, "steps": 10, "why": "wallbatch refuses: pair"}
    fake["sweep27"] = {"scene": "y", "N": 1000, "steps": 10, "wb_s": 2.0, "value": 0.5, "ratio": 0.5,
                       "path": "NumPy path"}
    lines = suite.markdown(fake).splitlines()
    assert lines[0] == "| scene | N | steps | wallbatch | LAMMPS | ratio | target | met |"
    assert len(lines) == 2 + len(suite.ROWS)
    by_row = {ln.split(" | ")[0].split("[")[-1].rstrip("]").split("]")[0]: ln for ln in lines[2:]}
    assert by_row["ljcut-4000"].endswith("| n/a (wallbatch refuses: pair) |")
    assert by_row["sweep27"].endswith("| no (NumPy path) |")
    assert by_row["gas-lj93-1000"].endswith("| >= 2 x LAMMPS | yes |")
    assert [ln.split("[")[0] for ln in suite.behind(fake)] == ["- y ", "- x "]
    fake["gas-lj93-10000"] = dict(fake["gas-lj93-1000"], N=10000, value=1.5, ratio=1.5)
    fake["gas-lj93-1000"] = dict(fake["gas-lj93-1000"], value=1.2, ratio=1.2)
    assert suite.behind(fake)[1] == ("- gas-lj93-1000 [gas-lj93-1000, gas-lj93-10000]: 1.20x (N = 1,000) / "
                                      "1.50x (N = 10,000); target >= 2 x LAMMPS: no")


def test_only_selects_by_name_and_pattern_and_refuses_unknown_names(suite):
    assert suite.select("ljcut-4000,ellipsoids-*") == ["ellipsoids-ees-1000", "ellipsoids-ees-10000", "ljcut-4000"]
    with pytest.raises(SystemExit, match="no row matches nope"):
        suite.select("nope")


def test_readme_section_is_replaced_between_its_markers_only(suite, tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"# top\n\n{suite.README_BEGIN}\nold table\n{suite.README_END}\n\nbottom\n")
    fake = {"gas-lj93-1000": {"scene": "gas", "N": 1000, "steps": 10, "wb": "0.1 s", "lmp": "0.3 s", "ratio": 3.0,
                              "value": 3.0},
            "threads-1e6": {"scene": "big", "N": 10**6, "steps": 10, "wb": "1 s", "value": 1.0, "ratio": 3.0}}
    suite.write_readme(readme, "Run HEAD", fake)
    text = readme.read_text()
    assert text.startswith("# top\n\n") and text.endswith("\n\nbottom\n") and "old table" not in text
    assert "Run HEAD" in text and "1 of 2 rows meet their target." in text
    assert "- big [threads-1e6]: 1 s; target >= 1.6 x one thread: no" in text
    real = (BENCH.parent / "README.md").read_text()
    assert real.count(suite.README_BEGIN) == 1 and real.count(suite.README_END) == 1


@pytest.mark.parametrize("make", ["ellipsoid_slit", "region_ees", "thermostat_langevin", "thermostat_nvt",
                                  "thermostat_berendsen", "gas_2d", "table_slit", "lepton_slit", "stochastic_slit",
                                  "flow_gas", "region_sphere", "hot_cold_slit",
                                  "stochastic_two_slit"])
def test_scenes_build_and_export_for_lammps_with_its_default_neighbor_settings(suite, make, tmp_path):
    common = suite.common
    if make.startswith("thermostat_"):
        cfg = common.thermostat_slit(40, make.split("_")[1], steps=10, thermo=5)
    elif make == "region_sphere":
        cfg = common.region_gas(40, "sphere", steps=10, thermo=5)
    else:
        cfg = getattr(common, make)(40, steps=10, thermo=5)
    case = common.build(cfg)
    assert isinstance(case, Case) and case.natoms == 40 and case.steps == 10
    setup, steps, exp = common.lammps_script(cfg, case, str(tmp_path))
    assert steps == 10 and exp.steps == 10
    assert not any(ln.startswith(("neigh_modify", "run")) for ln in setup)
    assert (tmp_path / exp.data_name).exists()


def fake_speed_row(suite, monkeypatch, wb_time, lmp_time, lammps: bool, repeat: int) -> tuple[dict, list[str]]:
    """`suite.speed` with wallbatch's and LAMMPS's runs faked: wb_time(calls so far) and lmp_time()
    give their seconds. Returns the row and the calls in order ("wb", "lmp")."""
    calls: list[str] = []

    class Result:
        status, error = "ok", ""

    def engine_run(case):
        calls.append("wb")
        return wb_time(len(calls)), Result(), "compiled"

    def lammps_export_run(cfg, case):
        calls.append("lmp")
        return lmp_time()

    monkeypatch.setattr(suite, "engine_run", engine_run)
    monkeypatch.setattr(suite, "lammps_export_run", lammps_export_run)
    monkeypatch.setattr(suite, "build", lambda cfg: Case.__new__(Case))
    monkeypatch.setattr(Case, "natoms", 1000, raising=False)
    monkeypatch.setattr(Case, "steps", 100, raising=False)
    monkeypatch.setattr(suite, "USE_LAMMPS", lammps)
    monkeypatch.setattr(suite, "REPEAT", repeat)
    return suite.speed("scene", {"run": {"steps": 100, "thermo": 10}}), calls


def test_repeat_times_both_codes_in_turns_and_keeps_the_best_of_each(suite, monkeypatch):
    wb_times, lmp_times = iter([0.01, 0.30, 0.20, 0.25]), iter([0.9, 1.1, 0.8])  # 0.01: the warm-up
    out, calls = fake_speed_row(suite, monkeypatch, lambda _: next(wb_times), lambda: next(lmp_times), True, 3)
    assert calls == ["wb"] + ["wb", "lmp"] * 3  # the warm-up, then in turns
    assert out["wb_s"] == 0.20 and out["lmp_s"] == 0.8 and out["ratio"] == pytest.approx(4.0)  # warm-up not kept
    monkeypatch.setattr(suite, "REPEAT", 1)
    assert "one measurement per cell" in suite.header("now", "cpu")
    monkeypatch.setattr(suite, "REPEAT", 2)
    assert "best of 2 measurements per cell" in suite.header("now", "cpu")


@pytest.mark.parametrize("wb, lmp, lammps, runs", [
    (0.05, 0.2, True, 6),    # wallbatch short: up to MAX_REPEAT
    (0.3, 0.1, True, 5),     # LAMMPS short: until it measured 0.5 s (5 x 0.1)
    (0.3, 0.3, True, 2),     # neither short (0.6 s each): REPEAT
    (0.05, None, False, 6),  # without LAMMPS, wallbatch alone decides
    (0.3, None, False, 2),
])
def test_a_short_row_is_measured_more_times_both_codes_in_turns(suite, monkeypatch, wb, lmp, lammps, runs):
    out, calls = fake_speed_row(suite, monkeypatch, lambda k: wb * (1 + 0.01 * k), lambda: lmp, lammps, 2)
    assert calls == ["wb"] + (["wb", "lmp"] if lammps else ["wb"]) * runs  # the warm-up, then in turns
    assert out["wb_s"] == pytest.approx(wb * 1.02)  # the best: the first timed run (later ones take longer)
    assert ("best of" in out.get("note", "")) == (runs > 2)


def test_two_core_probe_measures_what_two_threads_get_and_the_suite_reports_it(suite, monkeypatch):
    import threading
    import time

    import host_cores

    assert set(suite.TWO_CORE_ROWS) <= set(suite.ROWS)
    # two threads that never wait for each other do twice one thread's work; two that take turns, one's
    assert host_cores._capacity(time.sleep, lambda k: (0.05,)) == pytest.approx(2.0, rel=0.25)
    turn = threading.Lock()

    def one_at_a_time(seconds: float) -> None:
        with turn:
            time.sleep(seconds)

    assert host_cores._capacity(one_at_a_time, lambda k: (0.05,)) == pytest.approx(1.0, rel=0.25)
    monkeypatch.setattr(host_cores, "VECTOR_PASSES", 10)
    monkeypatch.setattr(host_cores, "CHAIN_STEPS", 1000)
    got = host_cores.probe(2)
    assert len(got["vector"]) == len(got["chain"]) == 2 and min(got["vector"] + got["chain"]) > 0
    assert host_cores.medians({"vector": [1.1, 1.3, 1.2], "chain": [1.9, 2.0, 1.95]}) == (1.2, 1.95)
    monkeypatch.setattr(suite, "PROBES", [(1.2, 1.95), (1.6, 1.9)])
    assert "an in-cache vector loop 1.20-1.60x, a latency-bound chain 1.90-1.95x" in suite.header("now", "cpu")
    monkeypatch.setattr(suite, "PROBES", [])
    assert "vector loop" not in suite.header("now", "cpu")


@pytest.mark.slow
def test_pair_probe_runs_two_independent_copies_of_the_pair_kernels(suite, monkeypatch):
    import host_cores

    from wallbatch.engine import pair_compiled as pc

    if not pc.enabled():
        pytest.skip("numba not importable")
    assert set(suite.PAIR_PROBE_ROWS) <= set(suite.TWO_CORE_ROWS)
    got = host_cores.pair_probe(2000, 2)
    assert sorted(got) == ["pair build", "pair forces"]
    assert all(len(v) == 2 and min(v) > 0 for v in got.values())
    # a force pass whose result depends on what else ran (here: on a call count) is caught
    real, calls = pc.forces_case, []

    def leaky(x, f, *args):  # noqa: ANN001, ANN002, ANN202
        real(x, f, *args)
        calls.append(1)
        f[0, 0] += len(calls)

    monkeypatch.setattr(pc, "forces_case", leaky)
    with pytest.raises(RuntimeError, match="differs from one run alone"):
        host_cores.pair_probe(2000, 1)
    text = suite.pair_probe_text({"pair forces": [1.3, 1.4, 1.5], "pair build": [1.2, 1.1, 1.3]})
    assert "force pass 1.40x, list build 1.20x one alone" in text


@pytest.mark.parametrize("variant, split", [(None, True), ("reflect", True), ("reflect-stats", False),
                                            ("dt-reset", False)])
def test_pair_threads_variants_are_the_scenes_they_name(suite, variant, split):
    """benchmarks/pair_threads.py --variant: the LJ liquid slit with reflect faces (split over threads
    like the lj93 walls), with their statistics or with fix dt/reset (which a case over threads runs
    on the per-step path)."""
    import pair_threads

    from wallbatch.engine import pair_compiled as pc
    from wallbatch.engine.engine import Engine

    cfg = pair_threads.scene(2000, 10, None, variant)
    assert cfg["walls"]["pore"]["style"] == ("reflect" if variant and variant.startswith("reflect") else "lj93")
    assert ("dt_reset" in cfg) == (variant == "dt-reset")
    engine = Engine([suite.common.build(cfg)])
    assert (engine.dt_reset is not None) == (variant == "dt-reset")
    if pc.enabled():
        assert pc.threads_take(engine.compiled_plan()) == split


def test_pair_split_cost_compares_the_split_with_the_whole_on_the_same_list(suite, monkeypatch, capsys):
    """benchmarks/pair_split_cost.py: the split pass and build give the whole's bits (it checks), and
    its table has both rows."""
    import pair_split_cost

    from wallbatch.engine import pair_compiled as pc

    if not pc.enabled():
        pytest.skip("numba not importable")
    monkeypatch.setattr(sys, "argv", ["pair_split_cost.py", "--atoms", "4000", "--rounds", "1"])
    pair_split_cost.main()
    out = capsys.readouterr().out
    assert "same forces and list bits: yes" in out
    assert "| force pass |" in out and "| list build + RowSplit |" in out
