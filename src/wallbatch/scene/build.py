"""Resolve a validated Config into a `Case`: plain arrays and frozen specs in box units, what the
engine runs. Atoms are created here (random, lattice, explicit positions, .npz file), with their
masses, radii and initial velocities.
"""

from __future__ import annotations

import contextlib
import dataclasses
import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from wallbatch.config.models import Config, TimeInterval, lattice_spacing
from wallbatch.config.profiles import profile_bins
from wallbatch.expr import Variables
from wallbatch.geometry.quaternion import normalize, random_quaternions
from wallbatch.geometry.regions import RegionGeom
from wallbatch.scene.datafile import DataFileError, read_data_file, select_ids
from wallbatch.scene.case import (
    Case,
    CaseError,
    DtResetSpec,
    Face,
    FlowSpec,
    MinimizeWarning,
    MinSettings,
    PairSpec,
    CustomWallSpec,
    ProfileSpec,
    ReflectSpec,
    StochasticSpec,
    RegionWallSpec,
    SoftWallSpec,
    Value,
)
from wallbatch.scene.ensemble import build_fixes
from wallbatch.styles import STYLES, WallStyle
from wallbatch.units import LATTICE_BASIS, LATTICE_CELL, LATTICE_POSITIONS, LATTICES_2D, UNIT_SYSTEMS, UnitSystem


def _fail(path: str, msg: str) -> CaseError:
    return CaseError(f"{path}: {msg}", key=path)


def _fail_at(cfg: Config, path: str, msg: str) -> CaseError:
    """A CaseError at the config field `path` (dotted), with the config's file:line:col when the
    config came from a file."""
    srcmap = getattr(cfg, "_srcmap", None)
    if srcmap is not None:
        loc = tuple(int(p) if p.isdigit() else p for p in path.split("."))
        with contextlib.suppress(Exception):
            return CaseError(srcmap.format(loc, msg))
    return _fail(path, msg)


def _check_finite_rows(cfg: Config, path: str, file: Path, name: str, arr: np.ndarray) -> None:
    """Every value of an atoms-file array finite: else name the file, the array and the atom."""
    if arr.size == 0:
        return
    bad = ~np.isfinite(arr.reshape(len(arr), -1)).all(axis=1)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise _fail_at(cfg, path, f"{file}: array {name} has a non-finite value (inf or nan) at row {i} "
                                  f"(atom {i + 1} of the file): {str(arr[i].tolist())[:200]}")


# ----------------------------------------------------------------------------- atoms


def _region_contains(cfg: Config, name: str, pts: np.ndarray) -> np.ndarray:
    """Points inside-or-on a region (side in), or strictly outside (side out)."""
    region = cfg.regions[name]
    return RegionGeom.from_config(region, None if region.units == "box" else lattice_spacing(cfg)).contains(pts)


PAIR_CHUNK = 1 << 19  # candidate pairs examined at once by _close_pairs (bounds its memory, ~40 MB)


def _cells(s: np.ndarray, boxsize: np.ndarray, ncell: np.ndarray) -> np.ndarray:
    """Integer cell coordinates (n, 3) of wrapped points `s` (in [0, boxsize)) on a grid of
    `ncell` cells per dimension."""
    c = np.floor(s * (ncell / boxsize)).astype(np.int64)
    return np.clip(c, 0, ncell - 1)


def _close_pairs(a: np.ndarray, b: np.ndarray | None, boxsize: np.ndarray, r: float,
                 dense: bool | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (i, j, d2) of points a[i], b[j] (b None: pairs i < j within a) whose squared distance
    d2 in the periodic metric of `boxsize` (per dimension min(|dx|, L - |dx|)) is at most about r^2:
    every pair with d <= r is in, and others in neighbouring cells too (the caller applies its own
    rule to d2). A cell list (cells at least r wide, found by sorting cell keys; 27 neighbour
    offsets, fewer when a dimension has under 3 cells), vectorised over the points; the points are
    wrapped into [0, boxsize). `dense` (None: chosen by size) looks the cells up in a table of
    every cell or by binary search of the sorted keys: the same pairs in the same order."""
    same = b is None
    b = a if same else b
    ncell = np.clip(np.floor(boxsize / (r * (1.0 + 1e-9))), 1, 1 << 20).astype(np.int64)
    ca, cb = _cells(a, boxsize, ncell), _cells(b, boxsize, ncell)
    key = (cb[:, 0] * ncell[1] + cb[:, 1]) * ncell[2] + cb[:, 2]
    order = np.argsort(key, kind="stable")
    ncells = int(np.prod(ncell))
    # a table of every cell's first point and count, unless it would dwarf the 27 lookups per point
    # of `a` (which a binary search of the sorted keys then answers: the same first point and count)
    if dense is None:
        dense = ncells <= 8 * (len(b) + 27 * len(a)) + 4096
    if dense:
        per_cell = np.bincount(key, minlength=ncells)
        first_in = np.cumsum(per_cell) - per_cell
    else:
        sorted_key = key[order]
    # neighbour cell offsets per dimension, no repeats; the K = kx ky kz cells of a point in the
    # order of np.meshgrid(..., indexing="ij") of these (x slowest)
    offsets = [np.array(sorted({o % int(n) for o in (-1, 0, 1)}), np.int64) for n in ncell]
    nk = len(offsets[0]) * len(offsets[1]) * len(offsets[2])
    block = max(1, (1 << 16) // nk)
    out_i, out_j, out_d = [], [], []
    for start in range(0, len(a), block):  # blocks of target points, all offsets at once
        stop = min(len(a), start + block)
        nb = [(ca[start:stop, d, None] + offsets[d][None, :]) % ncell[d] for d in range(3)]  # (points, k_d)
        want = ((nb[0][:, :, None, None] * ncell[1] + nb[1][:, None, :, None]) * ncell[2]
                + nb[2][:, None, None, :]).ravel()
        target = np.repeat(np.arange(start, stop), nk)
        if dense:
            lo, count = first_in[want], per_cell[want]
        else:
            lo = np.searchsorted(sorted_key, want, "left")
            count = np.searchsorted(sorted_key, want, "right") - lo
        full = count > 0  # cells holding points (the others add no pair)
        want, target, lo, count = want[full], target[full], lo[full], count[full]
        ends = np.cumsum(count)
        first = 0
        while first < len(want):  # runs of entries with at most ~PAIR_CHUNK pairs
            done = int(ends[first - 1]) if first else 0
            last = max(first + 1, int(np.searchsorted(ends, done + PAIR_CHUNK, "right")))
            cnt = count[first:last]
            total = int(ends[last - 1]) - done
            if total:
                i = np.repeat(target[first:last], cnt)
                j = order[np.repeat(lo[first:last] - (np.cumsum(cnt) - cnt), cnt) + np.arange(total)]
                if same:
                    keep = i < j
                    i, j = i[keep], j[keep]
                dx = np.abs(a[i] - b[j])
                dx = np.minimum(dx, boxsize - dx)
                d2 = dx[:, 0] * dx[:, 0] + dx[:, 1] * dx[:, 1] + dx[:, 2] * dx[:, 2]
                near = d2 <= r * r * (1.0 + 1e-6)
                out_i.append(i[near])
                out_j.append(j[near])
                out_d.append(d2[near])
            first = last
    if not out_i:
        empty = np.zeros(0, np.int64)
        return empty, empty, np.zeros(0)
    return np.concatenate(out_i), np.concatenate(out_j), np.concatenate(out_d)


def _random_positions(cfg: Config, spec: Any, rng: np.random.Generator, path: str,
                      existing: np.ndarray) -> np.ndarray:
    """`count` uniform random points in the box (or a region), at least `overlap` apart from each
    other and from atoms created before (minimum image in periodic dims).

    Rounds of 2 x (still needed) candidates (at least 64): a candidate closer than `overlap` to an
    accepted atom is dropped, then the later point of each candidate pair at most `overlap` apart.
    Distances are minimum-image in a box of the periodic lengths and, in fixed dims, of twice the
    length plus 2 overlap + 1 (no wrap inside the box); a NumPy cell list finds the close pairs."""
    lo = np.asarray(cfg.box.lo, float)
    hi = np.asarray(cfg.box.hi, float)
    length = hi - lo
    periodic = np.array([b == "p" for b in cfg.box.boundary])
    ov = spec.overlap or 0.0
    boxsize = np.where(periodic, length, 2 * length + 2 * ov + 1.0)
    accepted = [existing] if len(existing) else []
    n_have = 0
    for _ in range(200):
        need = spec.count - n_have
        if need <= 0:
            break
        cand = lo + rng.random((max(2 * need, 64), 3)) * length
        if cfg.dimension == 2:  # in the plane z = 0, as LAMMPS's create_atoms random (x, y draws unchanged)
            cand[:, 2] = 0.0
        if spec.region is not None:
            cand = cand[_region_contains(cfg, spec.region, cand)]
        if ov > 0 and len(cand):
            shifted = lambda p: np.mod(p - lo, boxsize)  # noqa: E731
            if accepted:
                old = np.concatenate(accepted)
                i, _, d2 = _close_pairs(shifted(cand), shifted(old), boxsize, ov)
                far = np.ones(len(cand), bool)
                far[i[np.sqrt(d2) < ov]] = False  # nearest accepted atom closer than overlap
                cand = cand[far]
            i, j, d2 = _close_pairs(shifted(cand), None, boxsize, ov)
            close = d2 <= ov * ov
            if np.any(close):
                keep = np.ones(len(cand), bool)
                keep[np.maximum(i, j)[close]] = False  # drop the later point of each close pair
                cand = cand[keep]
        cand = cand[:need]
        accepted.append(cand)
        n_have += len(cand)
    if n_have < spec.count:
        raise _fail(path, f"placed only {n_have} of {spec.count} atoms (overlap {ov}"
                    f"{', region ' + spec.region if spec.region else ''}): lower count or overlap")
    new = np.concatenate(accepted)[len(existing):]
    return new


def atom_count(cfg: Config) -> int:
    """The atoms a config creates, from the config and the headers of its atoms files, without
    building anything: random counts and explicit positions exactly; a lattice as the box
    volume over the cell volume times the basis (regions not applied); a LAMMPS data file its
    header's `N atoms`; an .npz archive the length of its `x`. A file that cannot be read
    counts 0 (the case then fails when it is built)."""
    n = 0
    for g in cfg.atoms:
        c = g.create
        if c.random is not None:
            n += c.random.count
        elif c.positions is not None:
            n += len(c.positions)
        elif c.lattice is not None and cfg.lattice is not None:
            a = lattice_spacing(cfg) or 0.0
            cell = a * np.asarray(LATTICE_CELL.get(cfg.lattice.style, (1.0, 1.0, 1.0)))
            cells = np.subtract(cfg.box.hi, cfg.box.lo) / np.where(cell > 0, cell, np.inf)
            if cfg.lattice.style in LATTICES_2D:
                cells[2] = 1.0
            n += int(min(float(np.prod(np.ceil(cells))) * LATTICE_BASIS[cfg.lattice.style], 1e18))
        elif c.file is not None:
            file = Path(c.file)
            n += _file_atom_count(file if file.is_absolute() else cfg._base_dir / file)
    return n


def _file_atom_count(file: Path) -> int:
    """Atoms in an atoms file from its header only: a data file's `N atoms` line, an .npz's x."""
    try:
        if _is_npz(file):
            fmt = np.lib.format
            with zipfile.ZipFile(file) as zf, zf.open("x.npy") as fh:
                read = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}.get(fmt.read_magic(fh))
                if read is not None:
                    shape = read(fh)[0]
                    return int(shape[0]) if shape else 0
            with np.load(file, allow_pickle=False) as npz:
                return len(npz["x"])
        with open(file, errors="replace") as fh:
            for k, line in enumerate(fh):
                words = line.split("#")[0].split()
                if k and len(words) == 2 and words[1] == "atoms":
                    return int(words[0])
                if k > 1000:
                    break
    except (OSError, ValueError, KeyError, IndexError, zipfile.BadZipFile):
        pass
    return 0


def _lattice_positions(cfg: Config, region: str | None) -> np.ndarray:
    a = lattice_spacing(cfg)
    lo = np.asarray(cfg.box.lo, float)
    hi = np.asarray(cfg.box.hi, float)
    basis = np.asarray(LATTICE_POSITIONS[cfg.lattice.style])
    cell = a * np.asarray(LATTICE_CELL.get(cfg.lattice.style, (1.0, 1.0, 1.0)))  # hex: (a, sqrt(3) a, a)
    ranges = [np.arange(np.floor(lo[d] / cell[d]) - 1, np.ceil(hi[d] / cell[d]) + 1) for d in range(3)]
    if cfg.lattice.style in LATTICES_2D:
        ranges[2] = np.zeros(1)  # 2-D lattices: one plane at z = 0, as LAMMPS
    cells = np.stack(np.meshgrid(*ranges, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = ((cells[:, None, :] + basis[None, :, :]) * cell).reshape(-1, 3)
    pts = pts[np.all((pts >= lo) & (pts < hi), axis=1)]
    if region is not None:
        pts = pts[_region_contains(cfg, region, pts)]
    return pts


def _is_npz(file: Path) -> bool:
    """A NumPy .npz archive (a zip file), as opposed to a LAMMPS data file (text)."""
    if file.suffix == ".npz":
        return True
    try:
        with open(file, "rb") as fh:
            return fh.read(2) == b"PK"
    except OSError:
        return False


def _data_file_atoms(cfg: Config, g: Any, file: Path, path: str) -> dict[str, np.ndarray]:
    """A group's atoms from a LAMMPS data file (all of them, or the atom IDs of `create.ids`),
    sorted by ID. The group's `mass` and `velocity` override the file's, as LAMMPS's `mass`,
    `set ... mass` and `velocity` commands do after `read_data`."""
    periodic = tuple(b == "p" for b in cfg.box.boundary)
    try:
        df = read_data_file(file, periodic=periodic)
    except DataFileError as exc:
        raise _fail_at(cfg, f"{path}.file", str(exc)) from None
    select = None
    if g.create.ids is not None:
        select = select_ids(df.ids, g.create.ids)
        if not select.any():
            raise _fail(f"{path}.ids", f"no atom of {file} has an ID in {g.create.ids}")
    data = df.arrays(select)
    if g.mass is not None:
        del data["mass"]
    elif np.any(np.isnan(data["mass"])):
        raise _fail(f"{path}.file", f"{file} gives no mass for atom type(s) "
                    f"{sorted(set(df.types[select if select is not None else slice(None)][np.isnan(data['mass'])].tolist()))}"
                    f" (no Masses line): give the group a mass")
    if g.velocity is not None:
        data.pop("v", None)
    return data


def _per_atom(value: Any, n: int, width: int, path: str) -> np.ndarray:
    arr = np.asarray(value, float)
    if arr.ndim == 1:
        return np.broadcast_to(arr, (n, width)).copy()
    if arr.shape != (n, width):
        raise _fail(path, f"expected one {width}-vector or {n} of them, got shape {arr.shape}")
    return arr


def _thermal_velocities(n: int, mass: np.ndarray, temperature: float, u: UnitSystem,
                        rng: np.random.Generator, dimension: int = 3) -> np.ndarray:
    """Gaussian velocities with zero net momentum, scaled to exactly `temperature` over d n - d
    degrees of freedom (LAMMPS `velocity create T seed dist gaussian mom yes`); in 2-D vz = 0."""
    if n < 2 or temperature == 0.0:
        return np.zeros((n, 3))
    return _to_temperature(_gaussian_velocities(mass, temperature, u, rng, dimension), mass, temperature, u,
                           dimension)


def _gaussian_velocities(mass: np.ndarray, temperature: float, u: UnitSystem, rng: np.random.Generator,
                         dimension: int) -> np.ndarray:
    """Gaussian components of variance kT/m per atom [velocity] (vz = 0 in 2-D), as drawn."""
    v = rng.standard_normal((len(mass), 3)) * np.sqrt(u.boltz * temperature / u.mvv2e / mass)[:, None]
    if dimension == 2:
        v[:, 2] = 0.0
    return v


def _to_temperature(v: np.ndarray, mass: np.ndarray, temperature: float, u: UnitSystem,
                    dimension: int) -> np.ndarray:
    """v less its centre-of-mass velocity, scaled to exactly `temperature` over d n - d degrees of
    freedom (n >= 2 atoms)."""
    v = v - (mass[:, None] * v).sum(axis=0) / mass.sum()
    n = len(mass)
    t_now = (u.mvv2e * mass[:, None] * v * v).sum() / ((dimension * n - dimension) * u.boltz)
    return v * np.sqrt(temperature / t_now)


def _shared_velocities(vs: list[np.ndarray], ms: list[np.ndarray], sets: dict[str, list[int]],
                       cfg: Config, u: UnitSystem) -> None:
    """Each `velocity.shared` set (label -> its groups' indices): the groups' Gaussian draws
    (vs[i], as drawn) made one set's, in place: zero net momentum and exactly the temperature over
    all their atoms (d n - d degrees of freedom; zeros below 2 atoms)."""
    for idx in sets.values():
        temperature = float(cfg.atoms[idx[0]].velocity.temperature)
        mass = np.concatenate([ms[i] for i in idx])
        if len(mass) < 2 or temperature == 0.0:
            v = np.zeros((len(mass), 3))
        else:
            v = _to_temperature(np.concatenate([vs[i] for i in idx]), mass, temperature, u, cfg.dimension)
        cut = np.cumsum([0] + [len(ms[i]) for i in idx])
        for k, i in enumerate(idx):
            vs[i] = v[cut[k]:cut[k + 1]]


def _build_atoms(cfg: Config, rng: np.random.Generator) -> dict[str, np.ndarray]:
    u = UNIT_SYSTEMS[cfg.units]
    xs, vs, ms, rs, gid = [], [], [], [], []
    shapes, quats, angmoms = [], [], []
    shared: dict[str, list[int]] = {}  # velocity.shared label -> its groups
    existing = np.zeros((0, 3))
    for i, g in enumerate(cfg.atoms):
        path = f"atoms.{i}"
        c = g.create
        data: dict[str, np.ndarray] = {}
        if c.positions is not None:
            x = np.asarray(c.positions, float)
        elif c.random is not None:
            x = _random_positions(cfg, c.random, rng, f"{path}.create.random", existing)
        elif c.lattice is not None:
            x = _lattice_positions(cfg, c.lattice.region)
            if len(x) == 0:
                raise _fail(f"{path}.create.lattice", "no lattice point falls inside the box/region")
        else:
            file = Path(c.file)
            file = file if file.is_absolute() else cfg._base_dir / file
            where = f"{path}.create.file"
            if not _is_npz(file):  # a LAMMPS data file (any name: data.NAME, NAME.data, ...)
                data = _data_file_atoms(cfg, g, file, f"{path}.create")
            else:
                try:
                    with np.load(file, allow_pickle=False) as npz:
                        data = {k: np.asarray(npz[k], float) for k in npz.files}
                except (OSError, ValueError, TypeError, EOFError, zipfile.BadZipFile) as exc:
                    raise _fail_at(cfg, where, f"cannot read {file} as a NumPy .npz archive: "
                                               f"{str(exc)[:200] or type(exc).__name__}") from None
            if "x" not in data or data["x"].ndim != 2 or data["x"].shape[1] != 3:
                got = f"shape {data['x'].shape}" if "x" in data else f"arrays {sorted(data)[:10]}"
                raise _fail_at(cfg, where, f"{file} needs an array x of shape (N, 3), got {got}")
            nfile = len(data["x"])  # 0 is allowed: a group may be empty (a scene with no atoms fails)
            for key, width in (("x", 3), ("v", 3), ("mass", 0), ("radius", 0), ("shape", 3), ("quat", 4),
                               ("angmom", 3)):
                if key not in data:
                    continue
                want = (nfile, width) if width else (nfile,)
                if data[key].shape != want:
                    raise _fail_at(cfg, where, f"{file}: array {key} has shape {data[key].shape}, expected {want} "
                                               f"(one row per atom of x)")
                _check_finite_rows(cfg, where, file, key, data[key])
            x = data["x"]
            if cfg.dimension == 2 and np.any(x[:, 2] != 0.0):
                k = int(np.nonzero(x[:, 2] != 0.0)[0][0])
                raise _fail_at(cfg, where, f"{file}: atom {k + 1} has z = {x[k, 2]:g} in a 2-D run (dimension: 2): "
                                           f"every atom has z = 0 (LAMMPS: Read_data atom z coord is non-zero for "
                                           f"2d simulation)")
        n = len(x)
        for key, given in (("mass", g.mass), ("radius", g.radius)):
            if key in data and given is not None:
                raise _fail(f"{path}.{key}", f"{key} is given both here and in {c.file}: keep one")
        if "v" in data and g.velocity is not None:
            raise _fail(f"{path}.velocity", f"velocities are given both here and in {c.file}: keep one")
        mass = data["mass"] if "mass" in data else np.full(n, g.mass if g.mass is not None else np.nan)
        if mass.shape != (n,) or not np.all(mass > 0):
            raise _fail(f"{path}.mass", "masses must be positive, one per atom")
        radius = data["radius"] if "radius" in data else np.full(n, g.radius or 0.0)
        for key, given in (("shape", g.shape), ("quat", g.orientation), ("angmom", g.angmom)):
            if key in data and given is not None:
                raise _fail(f"{path}.{'orientation' if key == 'quat' else key}",
                            f"{key} is given both here and in {c.file}: keep one")
        shape, quat, angmom = _ellipsoid_state(g, data, n, rng, path)
        if "v" in data:
            v = _per_atom(data["v"], n, 3, f"{path}.create.file")
        elif g.velocity is None:
            v = np.zeros((n, 3))
        elif g.velocity.values is not None:
            v = _per_atom(g.velocity.values, n, 3, f"{path}.velocity.values")
        elif g.velocity.shared is not None:  # drawn here, made the set's once every group is drawn
            v = _gaussian_velocities(mass, g.velocity.temperature, u, rng, cfg.dimension)
            shared.setdefault(g.velocity.shared, []).append(i)
        else:
            v = _thermal_velocities(n, mass, g.velocity.temperature, u, rng, cfg.dimension)
        xs.append(x)
        vs.append(v)
        ms.append(mass)
        rs.append(radius)
        shapes.append(shape)
        quats.append(quat)
        angmoms.append(angmom)
        gid.append(np.full(n, i))
        existing = np.concatenate([existing, x])
    _shared_velocities(vs, ms, shared, cfg, u)
    x = np.concatenate(xs)
    lo, hi = np.asarray(cfg.box.lo), np.asarray(cfg.box.hi)
    outside = np.nonzero(np.any((x < lo) | (x > hi), axis=1))[0]
    if len(outside):
        i = outside[0]
        raise _fail("atoms", f"atom ID {i + 1} at {x[i].tolist()} is outside the box {lo.tolist()} - {hi.tolist()}")
    out = {"x": x, "v": np.concatenate(vs), "mass": np.concatenate(ms),
           "radius": np.concatenate(rs), "group": np.concatenate(gid)}
    shape = np.concatenate(shapes)
    if np.any(shape > 0):  # only scenes with ellipsoids carry orientation state
        out.update(shape=shape, quat=np.concatenate(quats), angmom=np.concatenate(angmoms))
    return out


def _ellipsoid_state(g: Any, data: dict[str, np.ndarray], n: int, rng: np.random.Generator,
                     path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Semi-axes (n,3) (zeros: point atoms), unit quaternions (n,4) and angular momenta (n,3) of a
    group. Orientation: aligned (identity, the default), random (uniform on SO(3)), one
    quaternion [qw, qx, qy, qz] or a `quat` array from the .npz; quaternions are normalised."""
    if g.shape is None and g.orientation is None and g.angmom is None and not data.keys() & {"shape", "quat", "angmom"}:
        # point atoms: the values of the general path below (no draws), without its checks and
        # normalisation (~0.2 ms a case of a sweep)
        quat = np.zeros((n, 4))
        quat[:, 0] = 1.0
        return np.zeros((n, 3)), quat, np.zeros((n, 3))
    if "shape" in data:
        shape = _per_atom(data["shape"], n, 3, f"{path}.create.file")
    else:
        shape = np.broadcast_to(np.asarray(g.shape if g.shape is not None else (0.0, 0.0, 0.0), float), (n, 3)).copy()
    if np.any(shape < 0) or np.any((shape > 0).any(axis=1) & ~(shape > 0).all(axis=1)):
        raise _fail(f"{path}.shape", "ellipsoid semi-axes must all be > 0 (or all 0 for a point atom)")
    if "quat" in data:
        quat = _per_atom(data["quat"], n, 4, f"{path}.create.file")
    elif g.orientation == "random":
        quat = random_quaternions(rng, (n,))
    elif isinstance(g.orientation, tuple):
        quat = np.broadcast_to(np.asarray(g.orientation, float), (n, 4)).copy()
    else:
        quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    if not np.all(np.linalg.norm(quat, axis=1) > 0):
        raise _fail(f"{path}.orientation", "a quaternion of length 0 has no orientation")
    unit = np.abs(np.einsum("ij,ij->i", quat, quat) - 1.0) <= 2e-15  # already unit (e.g. a data file's)
    quat = np.where(unit[:, None], quat, normalize(quat)) if "quat" in data else normalize(quat)
    if "angmom" in data:
        angmom = _per_atom(data["angmom"], n, 3, f"{path}.create.file")
    elif g.angmom is not None:
        angmom = _per_atom(g.angmom.values, n, 3, f"{path}.angmom.values")
    else:
        angmom = np.zeros((n, 3))
    return shape, quat, angmom


# ----------------------------------------------------------------------------- walls


def _value(v: Any) -> Value:
    return v[2:] if isinstance(v, str) and v.startswith("v_") else v


def _faces(cfg: Config, fid: str, wall: Any, params: tuple[str, ...]) -> tuple[Face, ...]:
    spacing = 1.0 if wall.units == "box" else lattice_spacing(cfg)
    faces = []
    for name, spec in wall.faces():
        dim = "xyz".index(name[0])
        side = -1 if name.endswith("lo") else 1
        coord = spec.coord
        if coord == "EDGE":
            coord, scale = float(cfg.box.lo[dim] if side < 0 else cfg.box.hi[dim]), 1.0
        elif isinstance(coord, float):
            coord, scale = coord * spacing, 1.0
        else:
            coord, scale = _value(coord), spacing
        p = {k: _value(getattr(spec, k)) for k in params if getattr(spec, k, None) is not None}
        faces.append(Face(f"{fid}/{name}", name, dim, side, coord, scale, p))
    return tuple(faces)


def build_case(cfg: Config, seed_key: tuple[int, ...] = ()) -> Case:
    """Resolve a validated config into a Case. Randomness comes from a generator seeded with the
    master seed and `seed_key` (a case's sweep coordinates), never from the batch position."""
    u = UNIT_SYSTEMS[cfg.units]
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, *seed_key]))
    atoms = _build_atoms(cfg, rng)
    n = len(atoms["x"])
    group_names = tuple(g.group for g in cfg.atoms)

    def mask(group: str) -> np.ndarray:
        if group == "all":
            return np.ones(n, bool)
        return atoms["group"] == group_names.index(group)

    soft, reflect, regional, flows, flow_seeds, fix_order = [], [], [], [], [], []
    for fid, wall in cfg.walls.items():
        if wall.style == "reflect":
            reflect.append(ReflectSpec(fid, mask(wall.group), wall.frame, _faces(cfg, fid, wall, ())))
            continue
        if wall.style == "reflect/stochastic":
            reflect.append(_stochastic_spec(cfg, fid, wall, mask(wall.group), (cfg.seed, *seed_key, wall.seed,
                                                                                len(reflect))))
            continue
        if wall.style == "flow":
            scale = 1.0 if wall.units == "box" else lattice_spacing(cfg)
            flows.append(FlowSpec(fid, mask(wall.group), "xyz".index(wall.axis), wall.vflow, wall.temperature,
                                  np.asarray(wall.coords, float) * scale, wall.rule))
            flow_seeds.append((cfg.seed, *seed_key, wall.seed, len(flows)))
            continue
        group = mask(wall.group)
        entry = STYLES[wall.potential] if wall.style == "region" else STYLES.get(wall.style)
        if entry is not None or wall.style == "region/ees":
            if entry is not None and entry.needs_radius and np.any(atoms["radius"][group] <= 0):
                raise _fail(f"walls.{fid}", f"wall/{wall.style} {entry.name} requires extended particles "
                            f"(radius > 0)")
            needs_shape = wall.style == "region/ees" or entry.needs_shape
            if needs_shape and ("shape" not in atoms or np.any(atoms["shape"][group] <= 0)):
                raise _fail(f"walls.{fid}", f"wall/{wall.style} requires extended particles: every atom of group "
                            f"{wall.group} needs a shape (ellipsoid semi-axes)")
        fix_order.append(fid)
        if entry is not None and entry.per_face:
            soft.append(_per_face_spec(cfg, fid, wall, entry, group))
            continue
        if wall.style in ("region", "region/ees"):
            region = cfg.regions[wall.region]
            spacing = None if region.units == "box" else lattice_spacing(cfg)
            potential = STYLES[wall.potential] if wall.style == "region" else None
            keys = potential.params if potential is not None else ("epsilon", "sigma", "cutoff")
            params = {k: _value(getattr(wall, k)) for k in keys if getattr(wall, k, None) is not None}
            mode = getattr(wall, "cutoff_mode", "shift")
            if mode == "smooth":
                params["switch_on"] = float(wall.switch_on)
            regional.append(RegionWallSpec(fid, wall.style, wall.region, RegionGeom.from_config(region, spacing),
                                           potential, group, wall.energy, params,
                                           getattr(wall, "virial", False), mode))
        else:
            style = STYLES[wall.style]
            faces = _faces(cfg, fid, wall, style.params)
            if wall.cutoff_mode == "smooth":  # r_on joins each face's parameters (a number per case)
                faces = tuple(dataclasses.replace(f, params={**f.params, "switch_on": float(wall.switch_on)})
                              for f in faces)
            soft.append(SoftWallSpec(fid, style, group, wall.energy, faces,
                                     wall.virial and style.virial, wall.cutoff_mode))  # e.g. wall/ees has no virial
    dtr = None
    if cfg.dt_reset is not None:
        d = cfg.dt_reset
        xscale = 1.0 if d.units == "box" else lattice_spacing(cfg)
        dtr = DtResetSpec(d.every, mask(d.group), d.tmin, d.tmax, d.xmax * xscale, d.emax)
    thermo = cfg.run.thermo
    is_time = isinstance(thermo, TimeInterval)
    dt = cfg.timestep if cfg.timestep is not None else u.dt
    return Case(
        name=cfg.name, units=u,
        box_lo=np.asarray(cfg.box.lo, float), box_hi=np.asarray(cfg.box.hi, float),
        periodic=np.array([b == "p" for b in cfg.box.boundary]),
        x=atoms["x"], v=atoms["v"], mass=atoms["mass"], radius=atoms["radius"],
        atom_group=atoms["group"], group_names=group_names,
        dt=dt,
        variables=Variables(cfg.variables),
        variable_text=tuple((k, str(v)) for k, v in cfg.variables.items()),
        soft_walls=tuple(soft), reflect_walls=tuple(reflect), dt_reset=dtr,
        steps=cfg.run.steps, run_time=cfg.run.time,
        thermo=thermo.time if is_time else thermo, thermo_is_time=is_time,
        outputs=tuple(cfg.output.thermo) + (("flow_crossings",) if flows and "flow_crossings" not in
                                             cfg.output.thermo else ()),
        dump_every=cfg.output.dump.every if cfg.output.dump else 0,
        dump_fields=tuple(cfg.output.dump.fields) if cfg.output.dump else (),
        shape=atoms.get("shape"), quat=atoms.get("quat"), angmom=atoms.get("angmom"),
        pair=_pair_spec(cfg), region_walls=tuple(regional), flow_walls=tuple(flows),
        flow_seeds=tuple(flow_seeds), fix_order=tuple(fix_order), minimize=_min_settings(cfg, dt),
        fixes=build_fixes(cfg, mask, seed_key), dimension=cfg.dimension,
        profiles=_profiles(cfg, mask), average_start=_average_start(cfg),
    )


def _per_face_spec(cfg: Config, fid: str, wall: Any, entry: WallStyle, group: np.ndarray) -> CustomWallSpec:
    """A style built per face (wall/lepton: a compiled expression per face, params the cutoff and
    the expression's names; wall/table: a resampled table per face, files relative to the config,
    params the cutoff): the registry entry's face_style for each face."""
    faces, styles, signature = [], [], []
    values = wall.model_dump()
    for face, (_, spec) in zip(_faces(cfg, fid, wall, ()), wall.faces()):
        try:
            style, params, sig = entry.face_style(spec.model_dump(), values, str(cfg._base_dir))
        except ValueError as exc:
            raise _fail(f"walls.{fid}.{face.name}.{getattr(exc, 'key', 'expression')}", str(exc)) from None
        styles.append(style)
        signature.append(sig)
        faces.append(Face(face.label, face.name, face.dim, face.side, face.coord, face.scale, params))
    return CustomWallSpec(fid, styles[0], group, wall.energy, tuple(faces), virial=wall.virial,
                          face_styles=tuple(styles), signature=tuple(signature))


def _stochastic_spec(cfg: Config, fid: str, wall: Any, group: np.ndarray, seed: tuple[int, ...]) -> StochasticSpec:
    """wall/reflect/stochastic: faces with params temp, vx, vy, vz, ax, ay, az (ax for maxwell)."""
    faces = []
    for face, (_, spec) in zip(_faces(cfg, fid, wall, ()), wall.faces()):
        a = spec.accom
        acc = (0.0, 0.0, 0.0) if a is None else (a, a, a) if isinstance(a, float) else a
        params = {"temp": spec.temp, "vx": spec.vel[0], "vy": spec.vel[1], "vz": spec.vel[2],
                  "ax": acc[0], "ay": acc[1], "az": acc[2]}
        faces.append(Face(face.label, face.name, face.dim, face.side, face.coord, face.scale, params))
    return StochasticSpec(fid, group, f"stochastic/{wall.rstyle}", tuple(faces), seed=seed)


def _profiles(cfg: Config, mask: Any) -> tuple[ProfileSpec, ...]:
    """output.profiles in box units, binned by config.profiles.profile_bins."""
    out = []
    for name, p in cfg.output.profiles.items():
        axis = "xyz".index(p.axis)
        lo, hi = float(cfg.box.lo[axis]), float(cfg.box.hi[axis])
        nbins, delta = profile_bins(p, lo, hi)
        out.append(ProfileSpec(name, axis, lo, delta, nbins, p.every, p.repeat, p.freq,
                               tuple(p.quantities), mask(p.group)))
    return tuple(out)


def _average_start(cfg: Config) -> float:
    av = cfg.output.averages
    if av is None:
        return 0.0
    return float(av.time if av.time is not None else (av.start or 0))


def _pair_spec(cfg: Config) -> PairSpec | None:
    if cfg.pair is None:
        return None
    p = cfg.pair
    length = np.asarray(cfg.box.hi, float) - np.asarray(cfg.box.lo, float)
    for d, b in enumerate(cfg.box.boundary[:cfg.dimension]):  # (2-D: no pairs across z)
        if b == "p" and 2.0 * p.cutoff >= length[d]:  # pair forces use the minimum image
            raise _fail("pair.cutoff", f"{p.cutoff} must be less than half the periodic box length {length[d]:g} "
                        f"along {'xyz'[d]} (wallbatch takes each pair's nearest image; LAMMPS would use more "
                        f"than one): make the box longer than {2.0 * p.cutoff:g} along {'xyz'[d]} or the cutoff "
                        f"shorter")
    skin = 0.3 if cfg.units == "lj" else 2.0  # LAMMPS's default neighbor skin
    return PairSpec(p.epsilon, p.sigma, p.cutoff, p.shift, skin)


def _min_settings(cfg: Config, dt: float) -> Any:
    if cfg.minimize is None:
        return None
    quiet = [fid for fid, w in cfg.walls.items() if w.style not in ("reflect", "reflect/stochastic", "flow")
             and not w.energy]
    if quiet:
        warnings.warn(
            f"minimize: wall(s) {', '.join(quiet)} have energy: false, so (as in LAMMPS without fix_modify "
            f"energy yes) their forces act during minimization but their energy is not in the minimized "
            f"quantity; set energy: true on them for a consistent minimization", MinimizeWarning, stacklevel=2)
    m = cfg.minimize
    return MinSettings(etol=m.etol, ftol=m.ftol, maxiter=m.maxiter, maxeval=m.maxeval, style=m.style,
                       dmax=m.dmax, timestep=dt)


__all__ = ["atom_count", "Case", "CaseError", "Face", "SoftWallSpec", "ReflectSpec", "DtResetSpec", "PairSpec", "RegionWallSpec",
           "build_case"]
