"""fix wall/region and wall/region/ees on a batch: region surfaces as walls.
"""

from __future__ import annotations

import numpy as np

from wallbatch.engine.state import BatchState, Stacked, stack_values
from wallbatch.geometry.regions import LAMMPS_EES_MESSAGE, LAMMPS_MESSAGE, RegionGeom
from wallbatch.scene.case import RegionWallSpec
from wallbatch.styles.ees import EES, ees_energy_force_torque, ees_torque, sigma_n
from wallbatch.styles.base import Params, WallStyle
from wallbatch.styles.cutoff import CutoffStyle
from wallbatch.styles.flat import colloid

# ----------------------------------------------------------------------------- the kernel


class RegionWallKernel:
    """fix wall/region over a batch of C cases with the same region and style (physics.md §5).

    Parameters are (C,) arrays (or one equal-style variable name for the whole batch, resolved
    per step like the flat walls). The work is vectorised over (case, atom) pairs of the group and
    their flattened contacts.
    """

    def __init__(self, specs: list["RegionWallSpec"]):
        s0 = specs[0]
        if any(s.region != s0.region or s.potential is not s0.potential for s in specs):
            raise ValueError(f"walls.{s0.fix_id}: cases with different regions or styles cannot share a batch")
        self.fix_id = s0.fix_id
        self.region_name = s0.region_name
        self.geom: RegionGeom = s0.region
        self.style: WallStyle = s0.potential
        # the potential under the wall's cut-off mode (None for wall/region/ees)
        self.cutoff = CutoffStyle(s0.potential, s0.cutoff_mode) if s0.potential is not None else None
        self.energy_to_pe: bool = s0.energy
        self.virial: bool = getattr(s0, "virial", False)  # fix_modify virial: sum of F r, set on output steps
        self.last_virial: np.ndarray | None = None
        self.atoms = np.nonzero(s0.group)[0]
        self.params: dict[str, Stacked] = {
            k: stack_values([v if isinstance(v := s.params[k], str) else float(v) for s in specs],
                            f"{s0.fix_id} {k}") for k in s0.params}
        self._radius_checked = False

    def set_params(self, **values: np.ndarray | float | str) -> None:
        """Replace parameters: (C,) arrays, a number for every case, or a variable name."""
        for k, v in values.items():
            self.params[k] = v if isinstance(v, str) else np.asarray(v, float)

    def take(self, keep: np.ndarray) -> None:
        for k, v in self.params.items():
            if isinstance(v, np.ndarray) and v.ndim:
                self.params[k] = v[keep]

    def _resolve(self, state: "BatchState") -> dict[str, np.ndarray]:
        C = state.ncases
        p = {}
        for k, v in self.params.items():
            val = state.variable(v) if isinstance(v, str) else v
            p[k] = np.broadcast_to(np.asarray(val, float), (C,))
            entry = self.style if self.style is not None else EES  # wall/region/ees: the ees parameters
            low = entry.param(k).min if k in entry.params else None
            if isinstance(v, str) and low is not None and np.any(bad := p[k] < low):
                state.fail(np.nonzero(bad)[0], lambda c, k=k, val=p[k], low=low: (
                    f"walls.{self.fix_id}: variable {k} evaluated to {val[c]:g} < {low:g}: "
                    f"Variable evaluation in fix wall gave bad value"))
        return p

    def apply(self, state: "BatchState", outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """Add the region-wall forces to state.f. With `outputs`, return the fix's scalar (C,)
        (shifted energy) and vector (C,3) (the force the atoms exert on the wall)."""
        C = state.ncases
        G = self.atoms.size
        p = self._resolve(state)
        if self.style.needs_radius and not self._radius_checked:
            self._check_radius(state)
        N = state.x.shape[1]
        # (C*G, 3): pair k is case k // G, atom atoms[k % G] (a view when the group is every atom)
        xs = (state.x if G == N else state.x[:, self.atoms]).reshape(-1, 3)
        wrong = np.nonzero(~self.geom.contains(xs))[0]
        idx, delta, r = self.geom.contacts(xs, np.repeat(p["cutoff"], G))
        ci, ai = idx // G, self.atoms[idx % G]
        pa = {k: v[ci] for k, v in p.items()}
        if self.style.needs_radius:
            pa["radius"] = state.radius[ci, ai]
        close = r <= self.style.too_close(pa)
        if wrong.size or close.any():
            self._fail(state, wrong, ci[close], ai[close], r[close])
            ok = ~close
            ci, ai, delta, r = ci[ok], ai[ok], delta[ok], r[ok]
            pa = {k: v[ok] for k, v in pa.items()}
        if outputs:
            e, f = self.cutoff.energy_force(r, pa)
        else:
            f = self.cutoff.force(r, pa)
        fvec = (f / r)[:, None] * delta
        if state.f.flags.c_contiguous:  # an atom may have several contacts: unbuffered add
            np.add.at(state.f.reshape(-1, 3), ci * N + ai, fvec)
        else:
            np.add.at(state.f, (ci, ai), fvec)
        if not outputs:
            return None
        energy = np.bincount(ci, weights=e, minlength=C)
        if self.virial:  # trace of sum F_i del_j over contacts = F r (the flat walls' convention)
            self.last_virial = np.bincount(ci, weights=f * r, minlength=C)
        vector = -np.stack([np.bincount(ci, weights=fvec[:, d], minlength=C) for d in range(3)], axis=1)
        return energy, vector

    def _check_radius(self, state: "BatchState") -> None:
        bad = np.any(state.radius[:, self.atoms] <= 0.0, axis=1)
        if bad.any():
            state.fail(np.nonzero(bad)[0], lambda c: (
                f"walls.{self.fix_id} (wall/region {self.region_name} colloid): a group atom has radius 0 "
                f"(LAMMPS: Fix wall/region colloid requires only extended particles)"))
        self._radius_checked = True

    def _fail(self, state: "BatchState", wrong: np.ndarray, ci: np.ndarray, ai: np.ndarray,
              r: np.ndarray) -> None:
        """Fail every case with an atom on the wrong side or a contact with r <= tooclose; the
        message names the lowest such atom of the case."""
        G = self.atoms.size
        w_ci, w_ai = wrong // G, self.atoms[wrong % G]
        all_ci = np.concatenate([w_ci, ci])
        all_ai = np.concatenate([w_ai, ai])
        kind = np.concatenate([np.zeros(w_ci.size, int), np.ones(ci.size, int)])
        dist = np.concatenate([self.geom.distance(state.x[w_ci, w_ai]), r])
        order = np.lexsort((kind, all_ai, all_ci))
        rows, first = np.unique(all_ci[order], return_index=True)
        pick = order[first]
        info = {int(c): (int(all_ai[k]), int(kind[k]), float(dist[k])) for c, k in zip(rows, pick)}
        side = "outside" if self.geom.side == "in" else "inside (or on the surface of)"
        ees = self.style is None
        what = f"wall/region/ees {self.region_name}" if ees else f"wall/region {self.region_name} {self.style.name}"
        lammps = LAMMPS_EES_MESSAGE if ees else LAMMPS_MESSAGE

        def message(c: int) -> str:
            a, k, d = info[c]
            head = f"walls.{self.fix_id} ({what}): atom ID {a + 1} {state.at(c)}"
            if k == 0:
                body = (f"is {side} region {self.region_name} (side {self.geom.side}), {d:.6g} from its "
                        f"surface: it is on the wrong side")
            elif ees:
                body = (f"is at distance {d:.6g} from the surface of region {self.region_name}, not more than its "
                        f"sigma_n along the contact normal: the ellipsoid touches or crosses the surface")
            elif self.style.needs_radius:
                body = (f"is at distance {d:.6g} from the surface of region {self.region_name}, not more than "
                        f"its radius {float(state.radius[c, a]):.6g}: the particle touches or crosses the surface")
            else:
                body = f"is at distance {d:.6g} from the surface of region {self.region_name}: it is on the surface"
            return f"{head} {body} (LAMMPS: {lammps})"

        state.fail(rows, message)


class RegionEESKernel(RegionWallKernel):
    """fix wall/region/ees (physics.md §6): the ees energy, force and torque of §4.7 with the
    contact normal n = delta/r and sigma_n along n. Energy unshifted (LAMMPS). "Too close" is
    r <= sigma_n along the true normal (the decisions table; LAMMPS uses a per-axis sigma_n)."""

    def __init__(self, specs: list["RegionWallSpec"]):
        super().__init__(specs)
        self.style = None
        self.virial = False  # wall/region/ees has no virial

    def apply(self, state: "BatchState", outputs: bool) -> tuple[np.ndarray, np.ndarray] | None:

        C, G, N = state.ncases, self.atoms.size, state.x.shape[1]
        p = self._resolve(state)
        xs = (state.x if G == N else state.x[:, self.atoms]).reshape(-1, 3)
        wrong = np.nonzero(~self.geom.contains(xs))[0]
        idx, delta, r = self.geom.contacts(xs, np.repeat(p["cutoff"], G))
        ci, ai = idx // G, self.atoms[idx % G]
        normal = delta / r[:, None]
        q, shape = state.quat[ci, ai], state.shape[ci, ai]
        sn = sigma_n(q, shape, normal)
        close = r <= sn
        if wrong.size or close.any():
            self._fail(state, wrong, ci[close], ai[close], r[close])
            ok = ~close
            ci, ai, normal, r, sn, q, shape = ci[ok], ai[ok], normal[ok], r[ok], sn[ok], q[ok], shape[ok]
        e, f, tw = ees_energy_force_torque(r, sn, p["epsilon"][ci], p["sigma"][ci])
        fvec = f[:, None] * normal
        np.add.at(state.f.reshape(-1, 3), ci * N + ai, fvec)
        np.add.at(state.torque.reshape(-1, 3), ci * N + ai, ees_torque(q, shape, normal, tw))
        if not outputs:
            return None
        energy = np.bincount(ci, weights=e, minlength=C)
        vector = -np.stack([np.bincount(ci, weights=fvec[:, d], minlength=C) for d in range(3)], axis=1)
        return energy, vector


def lammps_region_colloid(r, p: Params) -> tuple[np.ndarray, np.ndarray]:
    """LAMMPS 22Jul2025's fix wall/region colloid (quirk #1, physics.md §5), NOT used by wallbatch.

    With D = r - R, A = eps sigma^6/7560 [ (6R - D)/D^7 + (D + 8R)/(D + 2R)^7 ] and
    B = [ 2R(D+R) + D(D+2R) (ln D - ln(D+2R)) ] / [D(D+2R)] (fix wall/colloid: E = A - eps B / 6):

    E = A + eps B / 6 - [ eps sigma^6/7560 rc^-9 - (eps/6) rc^-3 ]     (already "shifted")
    F = -F_wall/colloid(r, R)                                            (not -dE/dr)
    """

    eps, sigma, big_r, rc = p["epsilon"], p["sigma"], p["radius"], p["cutoff"]
    s6 = sigma ** 6
    d = r - big_r
    a = eps * s6 / 7560.0 * ((6.0 * big_r - d) / d ** 7 + (d + 8.0 * big_r) / (d + 2.0 * big_r) ** 7)
    b = (2.0 * big_r * (d + big_r) + d * (d + 2.0 * big_r) * (np.log(d) - np.log(d + 2.0 * big_r))) / (
        d * (d + 2.0 * big_r))
    energy = a + eps * b / 6.0 - (eps * s6 / 7560.0 / rc ** 9 - eps / 6.0 / rc ** 3)
    return energy, -colloid(r, p)[1]
