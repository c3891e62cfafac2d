"""Config models of `output.profiles` (LAMMPS compute chunk/atom bin/1d + fix ave/chunk) and
`output.averages` (where time averages start), and their cross-field checks.

    output:
      profiles:
        across: {axis: z, bins: 50, every: 10, repeat: 100, freq: 1000,
                 quantities: [density/number, temp], group: fluid}
      averages: {start: 2000}          # steps; or {time: 10.0} for a run to a simulated time
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, NonNegativeFloat, NonNegativeInt

from wallbatch.config.base import NoBoolNumbers
from wallbatch.config.source import KEY

PROFILE_QUANTITIES = ("density/number", "density/mass", "temp", "vx", "vy", "vz")


class Profile(NoBoolNumbers):
    """One binned axis, sampled every `every` steps, `repeat` samples averaged into one window
    ending at every multiple of `freq` (LAMMPS Nevery Nrepeat Nfreq). Give `bins` (equal bins
    over the box, LAMMPS `bin/1d ... units reduced`) or `delta` (bin width in box distance units,
    LAMMPS `bin/1d lower delta units box`); bins start at the box's lower bound."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    axis: Literal["x", "y", "z"]
    bins: int | None = None
    delta: float | None = None
    every: int
    repeat: int
    freq: int
    quantities: Annotated[list[Literal[PROFILE_QUANTITIES]], Field(min_length=1)]  # type: ignore[valid-type]
    group: str = "all"


class Averages(NoBoolNumbers):
    """Samples before `start` (a step, inclusive) or `time` (simulated time, inclusive) are left
    out of every `_mean` / `_sem`. Default: all samples."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    start: NonNegativeInt | None = None
    time: NonNegativeFloat | None = None


MAX_PROFILE_BINS = 1_000_000  # bins of one profile (memory: bins x windows x cases per quantity)


def profile_bins(p: Any, lo: float, hi: float) -> tuple[int, float]:
    """(bins, delta) of profile `p` over [lo, hi] along its axis [box units]: with `delta`,
    ceil(L / delta) bins (the last one may reach past the box, as LAMMPS bin/1d); with `bins`,
    delta = L / bins. At least one bin."""
    if p.bins is not None:
        return max(int(p.bins), 1), (hi - lo) / p.bins
    delta = float(p.delta)
    nbins = int((hi - lo) / delta)
    if lo + nbins * delta < hi:
        nbins += 1
    return max(nbins, 1), delta


def check_profiles(cfg: Any, groups: list[str]) -> list[tuple[tuple, str]]:
    """(path, message) per problem of output.profiles / output.averages (LAMMPS's own checks of
    fix ave/chunk, plus what a run must have for a window or an average to exist)."""
    problems: list[tuple[tuple, str]] = []
    add = lambda path, msg: problems.append((path, msg))  # noqa: E731
    steps = cfg.run.steps
    for name, p in cfg.output.profiles.items():
        at = ("output", "profiles", name)
        if not name.replace("_", "a").replace("-", "a").isalnum() or not (name[0].isalpha() or name[0] == "_"):
            add(at + (KEY,), f"profile name '{name}' must be a word (letters, digits, _): it names output variables")
        if (p.bins is None) == (p.delta is None):
            add(at, "give exactly one of bins (number of equal bins) or delta (bin width, box units)")
        if p.bins is not None and p.bins < 1:
            add(at + ("bins",), f"bins must be >= 1, got {p.bins}")
        if p.delta is not None and not p.delta > 0:
            add(at + ("delta",), f"delta (bin width) must be > 0, got {p.delta}")
        k = "xyz".index(p.axis)
        lo, hi = float(cfg.box.lo[k]), float(cfg.box.hi[k])
        length = hi - lo
        sized = p.bins >= 1 if p.delta is None and p.bins is not None else (
            p.bins is None and p.delta is not None and p.delta > 0)  # (else reported above)
        nbins = profile_bins(p, lo, hi)[0] if sized else 0
        if nbins > MAX_PROFILE_BINS:
            key = "bins" if p.bins is not None else "delta"
            add(at + (key,), f"{nbins:,.0f} bins across the box's {p.axis} ({length:g} long): at most "
                f"{MAX_PROFILE_BINS:,} (each window holds every bin of every quantity)")
        for key in ("every", "repeat", "freq"):
            if getattr(p, key) < 1:
                add(at + (key,), f"{key} must be >= 1 (LAMMPS: Illegal fix ave/chunk n{key} value: {getattr(p, key)})")
        if p.every >= 1 and p.repeat >= 1 and p.freq >= 1:
            if p.freq % p.every != 0:
                add(at + ("freq",), f"freq ({p.freq}) must be a multiple of every ({p.every}), as LAMMPS Nfreq "
                    f"and Nevery (LAMMPS: Inconsistent fix ave/chunk nevery/nrepeat/nfreq values)")
            elif p.repeat * p.every > p.freq:
                add(at + ("repeat",), f"repeat * every ({p.repeat} * {p.every} = {p.repeat * p.every}) must not "
                    f"exceed freq ({p.freq}): the samples of one window would overlap the previous one (LAMMPS: "
                    f"Inconsistent fix ave/chunk nevery/nrepeat/nfreq values)")
            if steps is not None and p.freq > steps:
                add(at + ("freq",), f"freq ({p.freq}) is longer than the run ({steps} steps): no window would "
                    f"close; the first window ends at step freq")
        if cfg.dimension == 2 and p.axis == "z":
            add(at + ("axis",), "a 2-d simulation (dimension: 2) has no z profile: use x or y")
        if p.group not in groups:
            add(at + ("group",), f"unknown group '{p.group}' (groups: {', '.join(groups)})")
        if cfg.run.time is not None:
            add(at, "profiles count steps (every/repeat/freq): they need a step-based run (run: {steps: N})")
    freqs = {name: p.freq for name, p in cfg.output.profiles.items()}
    first = next(iter(freqs), None)
    for name, freq in freqs.items():
        if freq != freqs[first]:  # one window axis (window, window_step) for every profile
            add(("output", "profiles", name, "freq"), f"profiles share one window axis: every profile's freq must "
                f"be the same ({first} has {freqs[first]}, {name} has {freq}): give them one freq")
            break
    av = cfg.output.averages
    if av is not None:
        if av.start is not None and av.time is not None:
            add(("output", "averages"), "give start (a step) or time (a simulated time), not both")
        elif av.start is not None:
            if cfg.run.time is not None:
                add(("output", "averages", "start"), "a run to a simulated time averages from a time: write "
                    "averages: {time: T}")
            elif steps is not None and av.start > steps:
                add(("output", "averages", "start"), f"start ({av.start}) is past the end of the run ({steps} "
                    f"steps): no sample would be averaged")
            elif steps is not None and cfg.output.profiles and first is not None and freqs[first] >= 1 and \
                    steps // freqs[first] * freqs[first] < av.start:
                last = steps // freqs[first] * freqs[first]
                add(("output", "averages", "start"), f"start ({av.start}) is after the last profile window (step "
                    f"{last}, every freq = {freqs[first]} steps): no window would be averaged; start at or before "
                    f"{last}")
        elif av.time is not None:
            if cfg.run.time is None:
                add(("output", "averages", "time"), "a step-based run averages from a step: write "
                    "averages: {start: STEP}")
            elif av.time > cfg.run.time:
                add(("output", "averages", "time"), f"time ({av.time:g}) is past the end of the run "
                    f"({cfg.run.time:g}): no sample would be averaged")
    return problems
