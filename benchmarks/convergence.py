"""Speed against error: a sweep over the timestep (and over fix dt/reset's xmax) of one scene, with
the cost and the error of every point, in wallbatch and (when installed) LAMMPS.

    python benchmarks/convergence.py [--atoms 4000] [--out benchmarks/convergence]

Scene: the lj93 gas slit of benchmarks/common.py (ideal gas, T = 1, N atoms), run for a simulated
time T = 64 x 0.128 with a sample every 0.128 (dt = 0.016 / 2^k, so every run samples the same
instants). Points:
  * wallbatch, fixed dt = 0.016 ... 0.0005;
  * wallbatch, fix dt/reset every step with xmax = 0.0025 ... 0.08 (a run to the time T);
  * LAMMPS, fixed dt (its `run` command; dt/reset runs to a time are not replayed in LAMMPS).
Error of a point, against a wallbatch run at dt = 0.00025 (the reference):
  * energy drift per unit time: |slope of a least-squares line through etot(t)| / N [energy/time];
  * trajectory error of wall_force and ke: RMS over the samples (and faces) of the difference to
    the reference, over the RMS of the reference.
Cost: seconds of the run (wallbatch: the engine run of the case; LAMMPS: `run`) and atom-steps/s.
Writes OUT.md (the table) and OUT.png (error against cost, log-log, both codes on one plot).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import build, fmt, gas_slit, lammps_module, lammps_run, numba_state  # noqa: E402

from wallbatch.engine.engine import run_cases  # noqa: E402

SAMPLE = 0.128
NSAMPLE = 64
TOTAL = SAMPLE * NSAMPLE
DTS = [0.016 / 2**k for k in range(6)]  # 0.016 ... 0.0005
REF_DT = 0.016 / 2**6  # 0.00025
XMAX = [0.0025, 0.005, 0.01, 0.02, 0.04, 0.08]


def scene(n: int, dt: float) -> dict:
    steps = int(round(TOTAL / dt))
    return gas_slit(n, "lj93", steps=steps, thermo=int(round(SAMPLE / dt)), dt=dt)


def dt_reset_scene(n: int, xmax: float) -> dict:
    cfg = scene(n, 0.004)
    cfg["dt_reset"] = {"every": 1, "xmax": xmax, "units": "box"}
    cfg["run"] = {"time": TOTAL, "thermo": {"time": SAMPLE}}
    return cfg


def errors(data: dict[str, np.ndarray], ref: dict[str, np.ndarray], natoms: int) -> dict[str, float]:
    """Energy drift per unit time per atom, and relative RMS trajectory errors of wall_force, ke."""
    t, e = data["time"], data["etot"]
    slope = np.polyfit(t, e, 1)[0]
    out = {"drift": abs(slope) / natoms}
    for name in ("wall_force", "ke"):
        a, b = np.asarray(data[name], float), np.asarray(ref[name], float)
        out[name] = float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b**2)))
    return out


def lammps_data(samples: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """LAMMPS thermo columns under wallbatch's names."""
    faces = sorted(k for k in samples if k.startswith("f_w["))
    return {"time": samples["time"], "etot": samples["etotal"], "ke": samples["ke"],
            "wall_force": np.stack([samples[k] for k in faces], axis=1)}


def run_point(cfg: dict) -> tuple[float, dict, int, int]:
    case = build(cfg)
    t0 = time.perf_counter()
    res = run_cases([case])[0]
    seconds = time.perf_counter() - t0
    if res.status != "ok":
        raise RuntimeError(f"{cfg['name']}: {res.error}")
    return seconds, res.data, case.natoms, int(res.data["step"][-1])


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4))
    styles = {"wallbatch dt": ("o-", "C0"), "wallbatch dt_reset": ("s--", "C2"), "LAMMPS dt": ("^-", "C3")}
    for series, (marker, color) in styles.items():
        pts = [r for r in rows if r["series"] == series]
        if not pts:
            continue
        cost = [r["seconds"] for r in pts]
        axes[0].loglog(cost, [max(r["wall_force"], 1e-18) for r in pts], marker, color=color, label=series)
        axes[1].loglog(cost, [max(r["drift"], 1e-18) for r in pts], marker, color=color, label=series)
        for r, c in zip(pts, cost):
            axes[0].annotate(r["label"], (c, max(r["wall_force"], 1e-18)), fontsize=6, xytext=(3, 3),
                             textcoords="offset points", color=color)
    axes[0].set(xlabel="cost [s]", ylabel="wall_force trajectory error (relative RMS)",
                title="trajectory error against cost")
    axes[1].set(xlabel="cost [s]", ylabel="|d etot / dt| per atom [energy/time]", title="energy drift against cost")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"lj93 gas slit, N = {rows[0]['N']}, T = {TOTAL:g}: wallbatch ({numba_state()}) and LAMMPS")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--atoms", type=int, default=4000)
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent / "convergence"))
    ap.add_argument("--no-lammps", action="store_true")
    args = ap.parse_args()
    n = args.atoms
    run_cases([build(gas_slit(1000, "lj93", steps=10, thermo=5))])  # load the compiled kernel first
    _, ref, _, _ = run_point(scene(n, REF_DT))
    rows = []
    for dt in DTS:
        sec, data, natoms, steps = run_point(scene(n, dt))
        rows.append({"series": "wallbatch dt", "label": f"dt={dt:g}", "N": natoms, "steps": steps, "seconds": sec,
                     **errors(data, ref, natoms)})
    for xmax in XMAX:
        sec, data, natoms, steps = run_point(dt_reset_scene(n, xmax))
        rows.append({"series": "wallbatch dt_reset", "label": f"xmax={xmax:g}", "N": natoms, "steps": steps,
                     "seconds": sec, **errors(data, ref, natoms)})
    if not args.no_lammps and lammps_module() is not None:
        for dt in DTS:
            case = build(scene(n, dt))
            sec, samples = lammps_run(case)
            rows.append({"series": "LAMMPS dt", "label": f"dt={dt:g}", "N": case.natoms, "steps": case.steps,
                         "seconds": sec, **errors(lammps_data(samples), ref, case.natoms)})
    head = ["series", "point", "N", "steps", "seconds", "atom-steps/s", "energy drift /atom/time",
            "wall_force error", "ke error"]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join([r["series"], r["label"], str(r["N"]), str(r["steps"]), fmt(r["seconds"], ".3f"),
                                        fmt(r["N"] * r["steps"] / r["seconds"], ".3g"), fmt(r["drift"], ".2e"),
                                        fmt(r["wall_force"], ".2e"), fmt(r["ke"], ".2e")]) + " |")
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    text = (f"Run {started}; reference: wallbatch at dt = {REF_DT:g}; wallbatch path: {numba_state()}.\n\n"
            + "\n".join(lines) + "\n")
    out = Path(args.out)
    out.with_suffix(".md").write_text(text)
    plot(rows, out.with_suffix(".png"))
    print(text)
    print(f"wrote {out.with_suffix('.md')} and {out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
