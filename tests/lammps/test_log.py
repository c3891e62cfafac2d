"""wallbatch.lammps.log, the one LAMMPS log reader: thermo tables and minimization statistics,
on hand-written logs and on logs LAMMPS 22Jul2025 writes (the numbers are checked against closed
forms, not against the reader)."""

from __future__ import annotations

import numpy as np
import pytest
from lammps_oracle import lammps_log, run_script

from wallbatch.lammps.log import last_thermo, minimize_stats, printed, thermo_tables

TWO_RUNS = """\
LAMMPS (22 Jul 2025 - Update 4)
Per MPI rank memory allocation (min/avg/max) = 4.193 | 4.193 | 4.193 Mbytes
   Step         PotEng          f_w      
         0  -1.1197011672932422 -1.1197011672932422
WARNING: Wall-particle overlap (../fix_wall.cpp:1)
        12  -1.9802550118455862 -1.9802550118455862
Loop time of 3.2388e-05 on 1 procs for 12 steps with 2 atoms

Minimization stats:
  Stopping criterion = energy tolerance
  Energy initial, next-to-last, final = 
     -1.11970116729324  -1.98025501184559  -1.98025501184559
  Force two-norm initial, final = 2.0215139 1.9232498e-13
  Force max component initial, final = 1.5863884 1.7763568e-13
  Final line search alpha, max atom move = 1 1.7763568e-13
  Iterations, force evaluations = 12 21

Total # of neighbors = 0
Neighbor list builds = 2
print "wb_min $(pe:%.17g) $(fnorm:%.17g)"
wb_min -1.9802550118455862 1.9232498273731374e-13
run 10
   Step          Time           KinEng    
        12   0.06   0
        22   0.11   nan
Loop time of 6.429e-06 on 1 procs for 10 steps with 2 atoms
   Step          Time
        22   0.11
"""


def test_every_table_in_order_with_its_header_and_rows():
    tables = thermo_tables(TWO_RUNS)
    assert [t.header for t in tables] == [("Step", "PotEng", "f_w"), ("Step", "Time", "KinEng"), ("Step", "Time")]
    assert tables[0].rows.tolist() == [[0.0, -1.1197011672932422, -1.1197011672932422],
                                       [12.0, -1.9802550118455862, -1.9802550118455862]]  # WARNING skipped
    assert tables[1].rows[:, :2].tolist() == [[12.0, 0.06], [22.0, 0.11]] and np.isnan(tables[1].rows[1, 2])
    assert tables[2].rows.tolist() == [[22.0, 0.11]]  # a run cut short (no "Loop time") still counts
    cols = tables[0].columns(["step", "pe", "f_w"])
    assert list(cols) == ["step", "pe", "f_w"] and cols["pe"].tolist() == [-1.1197011672932422, -1.9802550118455862]
    assert list(tables[0].columns()) == ["Step", "PotEng", "f_w"]
    with pytest.raises(ValueError, match="2 names for a table of 3 columns"):
        tables[0].columns(["step", "pe"])


def test_last_thermo_picks_the_last_table_of_that_width():
    assert last_thermo(TWO_RUNS).tolist() == [[22.0, 0.11]]
    assert last_thermo(TWO_RUNS, 3)[:, 0].tolist() == [12.0, 22.0]
    assert last_thermo(TWO_RUNS, 3).dtype == np.float64
    assert last_thermo("no table here", 4).shape == (0, 4)
    assert last_thermo(TWO_RUNS, 5).shape == (0, 5)


def test_minimize_stats_block():
    (st,) = minimize_stats(TWO_RUNS)
    assert st.stop_reason == "energy tolerance"
    assert (st.iterations, st.evaluations) == (12, 21)
    assert st.energy == (-1.11970116729324, -1.98025501184559, -1.98025501184559)  # from the next line
    assert st.fnorm2 == (2.0215139, 1.9232498e-13) and st.fnorm_inf == (1.5863884, 1.7763568e-13)
    assert st.fields["Final line search alpha, max atom move"] == "1 1.7763568e-13"
    assert "Neighbor list builds" not in st.fields  # the block ends at its blank line
    assert printed(TWO_RUNS, "wb_min") == [["-1.9802550118455862", "1.9232498273731374e-13"]]
    assert minimize_stats("no minimization") == []
    with pytest.raises(ValueError, match="without Iterations, force evaluations"):
        minimize_stats(TWO_RUNS.replace("  Iterations, force evaluations = 12 21\n", ""))


# ----------------------------------------------------------------------------- on LAMMPS's own logs

# Two atoms between lj93 walls at z = 0 and 10 (epsilon = sigma = 1, rc = 2.5, box units), each
# within reach of one wall only: E(z) = 2/15 z^-9 - z^-3 - E(2.5) per atom (physics.md's 9-3 form).
SCENE = """\
units lj
atom_style atomic
boundary f f f
region box block 0 10 0 10 0 10 units box
create_box 1 box
mass 1 1.0
create_atoms 1 single 5 5 1.2 units box
create_atoms 1 single 5 5 8.9 units box
pair_style zero 1.0
pair_coeff * *
fix w all wall/lj93 zlo 0.0 1.0 1.0 2.5 zhi 10.0 1.0 1.0 2.5 units box
fix_modify w energy yes
thermo_style custom step pe f_w
thermo_modify norm no format float %.17g
"""


def lj93(z: float) -> float:
    return 2.0 / 15.0 * z**-9 - z**-3


@pytest.mark.lammps
def test_run_script_reads_exact_thermo_columns():
    ref = run_script(SCENE + "run 0", ["step", "pe", "f_w"])
    want = lj93(1.2) + lj93(10.0 - 8.9) - 2 * lj93(2.5)
    assert ref["step"].tolist() == [0.0]
    assert ref["pe"][0] == pytest.approx(want, rel=1e-14) and ref["f_w"][0] == ref["pe"][0]


@pytest.mark.lammps
def test_minimize_then_run_log():
    """minimize then run: two tables, the stats between them; the minimum is the 9-3 wall's
    z0 = (2/5)^(1/6) for both atoms (E = 2 (lj93(z0) - lj93(2.5)))."""
    text = lammps_log(SCENE + 'minimize 1e-14 1e-14 1000 10000\nprint "wb_min $(pe:%.17g) $(fnorm:%.17g)"\n'
                      "fix n all nve\nrun 10")
    tables = thermo_tables(text)
    assert len(tables) == 2 and tables[0].header == tables[1].header == ("Step", "PotEng", "f_w")
    (st,) = minimize_stats(text)
    z0 = 0.4 ** (1.0 / 6.0)
    e_min = 2.0 * (lj93(z0) - lj93(2.5))
    assert st.iterations == tables[0].rows[-1, 0] == tables[1].rows[0, 0]  # the run goes on from there
    assert st.evaluations >= st.iterations and st.stop_reason in ("energy tolerance", "linesearch alpha is zero")
    assert st.energy[0] == pytest.approx(tables[0].rows[0, 1], rel=1e-14)
    assert st.energy[2] == pytest.approx(e_min, rel=1e-12) and st.fnorm2[1] < 1e-6
    (pe, fnorm), = printed(text, "wb_min")
    assert float(pe) == tables[1].rows[0, 1] and float(fnorm) == pytest.approx(st.fnorm2[1], rel=1e-6)
    assert np.all(tables[1].rows[:, 1] == pytest.approx(e_min, rel=1e-12))  # at rest in the minimum
