"""Resolved integrator and thermostat fixes (`fixes:`) of one case: group masks and numbers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from wallbatch.config.ensemble import (
    DEFAULT_FIXES,
    INTEGRATORS,
    BerendsenFix,
    LangevinFix,
    NvtFix,
    RescaleFix,
)
from wallbatch.scene.case import CaseError


@dataclass(frozen=True)
class EnsembleFixSpec:
    """One fix of `fixes:`. Numbers (temperatures, damp, window, fraction, drag) may differ
    between the cases of a batch; the rest is structure."""

    fix_id: str
    style: str  # nve | nve/asphere | nvt | langevin | temp/berendsen | temp/rescale | enforce2d
    group: np.ndarray  # (N,) bool
    t_start: float = 0.0
    t_stop: float = 0.0
    damp: float = 1.0
    window: float = 0.0
    fraction: float = 1.0
    drag: float = 0.0
    tchain: int = 3
    tloop: int = 1
    every: int = 1
    zero: bool = False
    tally: bool = False
    seed: tuple[int, ...] = ()  # langevin: random stream key (master seed, sweep coordinates, fix seed)
    group_name: str = "all"  # the group's name in the config (messages)

    @property
    def integrates(self) -> bool:
        return self.style in INTEGRATORS

    def structure(self) -> tuple:
        return (self.fix_id, self.style, self.group.tobytes(), self.tchain, self.tloop, self.every, self.zero,
                self.tally)


def build_fixes(cfg: Any, mask: Callable[[str], np.ndarray],
                seed_key: tuple[int, ...]) -> tuple[EnsembleFixSpec, ...] | None:
    """The case's fixes in config order; None for the default (nve on all, 3-D). A 2-D run
    without an enforce2d gets one on all atoms, applied after every other force."""
    given = cfg.fixes
    if given is None and cfg.dimension == 3:
        return None
    out: list[EnsembleFixSpec] = []
    if given is None:
        out = [EnsembleFixSpec(fid, f["style"], mask(f["group"])) for fid, f in DEFAULT_FIXES.items()]
    else:
        for k, (fid, f) in enumerate(given.items()):
            group = mask(f.group)
            if isinstance(f, (NvtFix, LangevinFix, BerendsenFix, RescaleFix)) and not group.any():
                msg = f"group '{f.group}' has no atoms: fix {f.style} needs atoms to thermostat"
                where = getattr(cfg, "_srcmap", None)
                if where is not None:  # (placed here already)
                    raise CaseError(where.format(("fixes", fid, "group"), msg))
                raise CaseError(f"fixes.{fid}.group: {msg}", key=f"fixes.{fid}.group")
            kw: dict[str, Any] = {}
            if isinstance(f, NvtFix):
                kw = {"t_start": f.temp[0], "t_stop": f.temp[1], "damp": f.damp, "tchain": f.tchain,
                      "tloop": f.tloop, "drag": f.drag}
            elif isinstance(f, LangevinFix):
                kw = {"t_start": f.temp[0], "t_stop": f.temp[1], "damp": f.damp, "zero": f.zero,
                      "tally": f.tally, "seed": (cfg.seed, *seed_key, f.seed, k)}
            elif isinstance(f, BerendsenFix):
                kw = {"t_start": f.temp[0], "t_stop": f.temp[1], "damp": f.damp}
            elif isinstance(f, RescaleFix):
                kw = {"t_start": f.temp[0], "t_stop": f.temp[1], "every": f.every, "window": f.window,
                      "fraction": f.fraction}
            out.append(EnsembleFixSpec(fid, f.style, group, group_name=f.group, **kw))
    if getattr(cfg, "dimension", 3) == 2 and not any(s.style == "enforce2d" for s in out):
        out.append(EnsembleFixSpec("__enforce2d__", "enforce2d", mask("all")))
    return tuple(out)


def is_plain_nve(fixes: tuple[EnsembleFixSpec, ...] | None) -> bool:
    """True when the fixes are just velocity Verlet on every atom (the engine's built-in step)."""
    if fixes is None:
        return True
    if not fixes or any(f.style not in ("nve", "nve/asphere") for f in fixes):
        return False
    counts = np.sum([f.group for f in fixes], axis=0)
    return bool(np.all(counts == 1))
