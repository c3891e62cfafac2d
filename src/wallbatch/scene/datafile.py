"""LAMMPS data files as an atom source (`create: {file: state.data}`) and a writer for them.

Reads `atom_style` atomic, sphere and ellipsoid data files as LAMMPS's `read_data` does:

* header: `N atoms`, `N atom types`, `N ellipsoids`, `xlo xhi` / `ylo yhi` / `zlo zhi` (an
  orthogonal box; a tilted one, `xy xz yz`, is refused), counts of bonds etc. must be 0;
* `Masses` (`type mass`, per type), `Atoms` (`# style` comment optional), `Velocities`,
  `Ellipsoids`; other sections (`Pair Coeffs`, ...) are skipped;
* Atoms rows: atomic `id type x y z`, sphere `id type diameter density x y z`, ellipsoid
  `id type ellipsoidflag density x y z`, each optionally followed by image flags `ix iy iz`;
* Velocities rows: `id vx vy vz`, sphere `id vx vy vz wx wy wz` (the angular velocity is not
  used: wallbatch's spheres do not rotate), ellipsoid `id vx vy vz Lx Ly Lz` (angular momentum);
* Ellipsoids rows: `id 2a 2b 2c qw qx qy qz`: LAMMPS data files hold the *diameters* of the
  ellipsoid, wallbatch's `shape` is the semi-axes a, b, c (half of them);
* masses: atomic from `Masses`; sphere: density * volume of the sphere (`density` itself for a
  point particle of diameter 0), ellipsoid: density * volume of the ellipsoid (`density` itself
  with ellipsoidflag 0), in LAMMPS's order of operations.

Atoms are returned sorted by atom ID, so the k-th atom (1-based) of a file with IDs 1..N has ID k:
wallbatch's messages name atoms by that LAMMPS ID. A position outside the box along a periodic
dimension is wrapped into it and its image flag changed (as `read_data` does); `unwrapped()` gives
x + image * L. wallbatch itself does not track image flags.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["DataFile", "DataFileError", "id_ranges", "parse_id_ranges", "read_data_file", "write_data_file"]

ATOM_STYLES = ("atomic", "sphere", "ellipsoid")
_SECTIONS = ("Atoms", "Velocities", "Masses", "Ellipsoids", "Pair Coeffs", "PairIJ Coeffs", "Bonds", "Angles",
             "Dihedrals", "Impropers", "Bond Coeffs", "Angle Coeffs", "Dihedral Coeffs", "Improper Coeffs",
             "Lines", "Triangles", "Bodies")
_UNSUPPORTED_COUNTS = ("bonds", "angles", "dihedrals", "impropers", "lines", "triangles", "bodies")
_FOUR_PI_3 = 4.0 * math.pi / 3.0


class DataFileError(ValueError):
    """A data file wallbatch cannot read; the message names the file and line."""


@dataclass
class DataFile:
    """The atoms of a LAMMPS data file, sorted by ID, in box units.

    `mass` is NaN where the file gives none (atomic style without a `Masses` entry); `v` is None
    without a `Velocities` section; `shape` (semi-axes), `quat` and `angmom` only for ellipsoid
    files. `image` holds the image flags (after wrapping into the box)."""

    style: str
    box_lo: np.ndarray
    box_hi: np.ndarray
    ids: np.ndarray  # (N,) int64
    types: np.ndarray  # (N,) int64
    x: np.ndarray  # (N, 3)
    image: np.ndarray  # (N, 3) int64
    mass: np.ndarray  # (N,)
    radius: np.ndarray  # (N,)
    v: np.ndarray | None = None  # (N, 3)
    shape: np.ndarray | None = None  # (N, 3) semi-axes, 0 for point particles
    quat: np.ndarray | None = None  # (N, 4)
    angmom: np.ndarray | None = None  # (N, 3)
    type_masses: dict[int, float] = field(default_factory=dict)

    @property
    def natoms(self) -> int:
        return len(self.ids)

    def unwrapped(self, periodic: tuple[bool, bool, bool] = (True, True, True)) -> np.ndarray:
        """x + image * L along the periodic dimensions."""
        length = self.box_hi - self.box_lo
        return self.x + np.where(np.asarray(periodic), self.image * length, 0.0)

    def arrays(self, select: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """The per-atom arrays build_case reads (`x`, `mass`, `radius`, and `v`, `shape`, `quat`,
        `angmom` when the file has them), optionally for a subset (boolean mask)."""
        keep = slice(None) if select is None else select
        out = {"x": self.x[keep], "mass": self.mass[keep]}
        if self.style == "sphere":
            out["radius"] = self.radius[keep]
        for key in ("v", "shape", "quat", "angmom"):
            value = getattr(self, key)
            if value is not None:
                out[key] = value[keep]
        return out


def _clean(line: str) -> str:
    return line.split("#", 1)[0].strip()


def read_data_file(path: str | Path, atom_style: str | None = None,
                   periodic: tuple[bool, bool, bool] = (True, True, True)) -> DataFile:
    """Read a LAMMPS data file (see the module docstring). `atom_style` (atomic | sphere |
    ellipsoid) is taken from the `Atoms # style` comment when not given, else guessed from the
    column count (7 or 10 columns: ellipsoid when the file has an Ellipsoids section, else sphere).
    `periodic`: the dimensions along which positions outside the box are wrapped into it."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read the data file: {exc.strerror}") from None
    where = lambda k: f"{path}:{k + 1}"

    counts: dict[str, int] = {}
    bounds: dict[str, tuple[float, float]] = {}
    k = 1  # line 0 is the title
    while k < len(lines):
        text = _clean(lines[k])
        if not text:
            k += 1
            continue
        if text in _SECTIONS or text.split()[0] in _SECTIONS:
            break
        words = text.split()
        try:
            if len(words) == 4 and words[2:] in (["xlo", "xhi"], ["ylo", "yhi"], ["zlo", "zhi"]):
                bounds[words[2][0]] = (float(words[0]), float(words[1]))
            elif len(words) == 6 and words[3:] == ["xy", "xz", "yz"]:
                if any(float(w) != 0.0 for w in words[:3]):
                    raise DataFileError(f"{where(k)}: a triclinic (tilted) box cannot be read: wallbatch boxes "
                                        f"are orthogonal")
            elif words[0].lstrip("+-").isdigit():
                counts[" ".join(words[1:])] = int(words[0])
            else:
                raise ValueError
        except ValueError:
            raise DataFileError(f"{where(k)}: cannot read the header line {lines[k].strip()!r}") from None
        k += 1
    for key in _UNSUPPORTED_COUNTS:
        if counts.get(key, 0):
            raise DataFileError(f"{path}: the file has {counts[key]} {key}: wallbatch has no molecular topology "
                                f"(only atomic, sphere and ellipsoid atoms)")
    if "atoms" not in counts:
        raise DataFileError(f"{path}: the header has no 'N atoms' line")
    missing = [d for d in "xyz" if d not in bounds]
    if missing:
        raise DataFileError(f"{path}: the header has no {' '.join(f'{d}lo {d}hi' for d in missing)} line")
    natoms = counts["atoms"]
    ntypes = counts.get("atom types", 1)

    # sections: header line index, name, style comment, body lines (index, text)
    sections: dict[str, tuple[int, str, list[tuple[int, str]]]] = {}
    current: str | None = None
    while k < len(lines):
        raw = lines[k]
        text = _clean(raw)
        if text in _SECTIONS:
            current = text
            comment = raw.split("#", 1)[1].strip() if "#" in raw else ""
            if current in sections:
                raise DataFileError(f"{where(k)}: section {current} appears twice")
            sections[current] = (k, comment, [])
        elif text:
            if current is None:
                raise DataFileError(f"{where(k)}: unexpected line {raw.strip()!r} before any section")
            sections[current][2].append((k, text))
        k += 1
    if "Atoms" not in sections:
        raise DataFileError(f"{path}: no Atoms section")

    atoms_at, comment, rows = sections["Atoms"]
    if len(rows) != natoms:
        raise DataFileError(f"{where(atoms_at)}: the Atoms section has {len(rows)} lines, the header says "
                            f"{natoms} atoms")
    ncol = {len(r.split()) for _, r in rows}
    if atom_style is None and comment:
        atom_style = comment.split()[0]
    if atom_style is None:
        width = min(ncol) if ncol else 5
        atom_style = "atomic" if width in (5, 8) else (
            "ellipsoid" if ("Ellipsoids" in sections or "ellipsoids" in counts) else "sphere")
    if atom_style not in ATOM_STYLES:
        raise DataFileError(f"{where(atoms_at)}: atom_style {atom_style} cannot be read (atomic, sphere or "
                            f"ellipsoid)")
    base = 5 if atom_style == "atomic" else 7
    table = _table(rows, (base, base + 3), where, "Atoms", atom_style)
    ids = table[:, 0].astype(np.int64)
    if np.any(table[:, 0] != ids) or np.any(table[:, 1] != np.round(table[:, 1])):
        raise DataFileError(f"{where(atoms_at)}: atom IDs and types must be integers")
    types = table[:, 1].astype(np.int64)
    if len(np.unique(ids)) != natoms or np.any(ids < 1):
        raise DataFileError(f"{where(atoms_at)}: atom IDs must be positive and unique")
    if np.any((types < 1) | (types > ntypes)):
        bad = int(np.flatnonzero((types < 1) | (types > ntypes))[0])
        raise DataFileError(f"{where(rows[bad][0])}: atom type {types[bad]} is outside 1..{ntypes} (atom types in "
                            f"the header)")
    x = table[:, base - 3:base].copy()
    image = table[:, base:base + 3].astype(np.int64) if table.shape[1] == base + 3 else np.zeros((natoms, 3), np.int64)
    lo = np.array([bounds[d][0] for d in "xyz"])
    hi = np.array([bounds[d][1] for d in "xyz"])
    if np.any(hi <= lo):
        raise DataFileError(f"{path}: box bounds must have lo < hi")

    order = np.argsort(ids, kind="stable")
    ids, types, x, image, table = ids[order], types[order], x[order], image[order], table[order]

    # wrap positions outside a periodic box (read_data's remap)
    length = hi - lo
    for d in range(3):
        if periodic[d]:
            shift = np.floor((x[:, d] - lo[d]) / length[d]).astype(np.int64)
            out = (x[:, d] < lo[d]) | (x[:, d] >= hi[d])
            x[out, d] -= shift[out] * length[d]
            image[out, d] += shift[out]
        else:
            image[:, d] = 0

    type_masses: dict[int, float] = {}
    if "Masses" in sections:
        for line_no, text in sections["Masses"][2]:
            words = text.split()
            try:
                t, m = int(words[0]), float(words[1])
            except (ValueError, IndexError):
                raise DataFileError(f"{where(line_no)}: a Masses line is 'type mass', got {text!r}") from None
            if m <= 0:
                raise DataFileError(f"{where(line_no)}: mass of type {t} must be > 0")
            type_masses[t] = m
    shape = quat = angmom = None
    if atom_style == "atomic":
        radius = np.zeros(natoms)
        mass = np.array([type_masses.get(int(t), np.nan) for t in types], float)
    elif atom_style == "sphere":
        diameter, density = table[:, 2], table[:, 3]
        radius = 0.5 * diameter
        if np.any(radius < 0) or np.any(density <= 0):
            raise DataFileError(f"{where(atoms_at)}: sphere diameters must be >= 0 and densities > 0")
        mass = np.where(radius > 0, _FOUR_PI_3 * radius * radius * radius * density, density)
    else:
        flag, density = table[:, 2], table[:, 3]
        if np.any((flag != 0) & (flag != 1)) or np.any(density <= 0):
            raise DataFileError(f"{where(atoms_at)}: ellipsoid flags must be 0 or 1 and densities > 0")
        radius = np.zeros(natoms)
        shape = np.zeros((natoms, 3))
        quat = np.tile([1.0, 0.0, 0.0, 0.0], (natoms, 1))
        angmom = np.zeros((natoms, 3))
        mass = density.copy()
        if "Ellipsoids" in sections:
            at, _, erows = sections["Ellipsoids"]
            etab = _table(erows, (8,), where, "Ellipsoids", "ellipsoid")
            n = _positions(ids, etab[:, 0], erows, where, "Ellipsoids")
            bad = np.flatnonzero(flag[n] != 1)
            if bad.size:
                raise DataFileError(f"{where(erows[bad[0]][0])}: atom ID {int(etab[bad[0], 0])} is not an ellipsoid "
                                    f"(ellipsoidflag 1) of the Atoms section")
            if np.any(etab[:, 1:4] <= 0):
                raise DataFileError(f"{where(at)}: ellipsoid diameters must be > 0")
            if np.any(np.all(etab[:, 4:8] == 0, axis=1)):
                raise DataFileError(f"{where(at)}: a quaternion of length 0 has no orientation")
            shape[n] = 0.5 * etab[:, 1:4]
            quat[n] = etab[:, 4:8]
        missing_shape = (flag == 1) & np.all(shape == 0, axis=1)
        if np.any(missing_shape):
            raise DataFileError(f"{path}: atom ID {int(ids[np.flatnonzero(missing_shape)[0]])} has ellipsoidflag 1 "
                                f"but no line in the Ellipsoids section")
        ell = flag == 1
        vol = _FOUR_PI_3 * shape[:, 0] * shape[:, 1] * shape[:, 2]
        mass = np.where(ell, density * vol, density)
    v = None
    if "Velocities" in sections:
        at, _, vrows = sections["Velocities"]
        width = 4 if atom_style == "atomic" else 7
        vtab = _table(vrows, (width,), where, "Velocities", atom_style)
        v = np.zeros((natoms, 3))
        n = _positions(ids, vtab[:, 0], vrows, where, "Velocities")
        v[n] = vtab[:, 1:4]
        if atom_style == "ellipsoid":
            angmom[n] = vtab[:, 4:7]
        seen = np.zeros(natoms, bool)
        seen[n] = True
        if not seen.all():
            raise DataFileError(f"{where(at)}: the Velocities section misses atom ID "
                                f"{int(ids[np.flatnonzero(~seen)[0]])}")
    return DataFile(atom_style, lo, hi, ids, types, x, image, mass, radius, v, shape, quat, angmom, type_masses)


def _positions(ids: np.ndarray, wanted: np.ndarray, rows: list[tuple[int, str]], where, section: str) -> np.ndarray:
    """Indices (into the ID-sorted atoms) of the IDs a section's rows name."""
    k = np.searchsorted(ids, wanted)
    k = np.minimum(k, len(ids) - 1)
    bad = np.flatnonzero(ids[k] != wanted)
    if bad.size:
        raise DataFileError(f"{where(rows[bad[0]][0])}: atom ID {int(wanted[bad[0]])} in the {section} section is "
                            f"not in the Atoms section")
    return k


def _table(rows: list[tuple[int, str]], widths: tuple[int, ...], where, section: str, style: str) -> np.ndarray:
    out = []
    for line_no, text in rows:
        words = text.split()
        if len(words) not in widths:
            raise DataFileError(f"{where(line_no)}: a {section} line of atom_style {style} has "
                                f"{' or '.join(map(str, widths))} values, got {len(words)}: {text!r}")
        try:
            vals = [float(w) for w in words]
        except ValueError:
            raise DataFileError(f"{where(line_no)}: not a number in {text[:200]!r}") from None
        if not all(math.isfinite(v) for v in vals):
            raise DataFileError(f"{where(line_no)}: a non-finite value (inf or nan) in the {section} line "
                                f"{text[:200]!r}")
        out.append(vals)
    width = max(len(r) for r in out) if out else widths[0]
    if out and any(len(r) != width for r in out):
        raise DataFileError(f"{where(rows[0][0])}: {section} lines mix rows with and without image flags")
    return np.array(out, float).reshape(-1, width)


# ----------------------------------------------------------------------------- atom ID selections


def parse_id_ranges(text: str) -> list[tuple[int, int]]:
    """LAMMPS ID ranges `1:200 305 400:410` (`a:b` inclusive, `a*b` also accepted) -> [(a, b)]."""
    out = []
    for word in str(text).replace(",", " ").split():
        m = re.fullmatch(r"(\d+)(?:[:*](\d+))?", word)
        if not m:
            raise ValueError(f"bad atom ID range {word!r}: write IDs as 1:200 305 (inclusive ranges)")
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) else a
        if b < a:
            raise ValueError(f"bad atom ID range {word!r}: the end is smaller than the start")
        out.append((a, b))
    if not out:
        raise ValueError("empty atom ID selection")
    return out


def select_ids(ids: np.ndarray, text: str) -> np.ndarray:
    """Boolean mask of the IDs within the ranges of `text`."""
    mask = np.zeros(len(ids), bool)
    for a, b in parse_id_ranges(text):
        mask |= (ids >= a) & (ids <= b)
    return mask


def id_ranges(ids: np.ndarray) -> str:
    """Sorted IDs as LAMMPS ranges: `1:200 305:310 400`."""
    idx = np.unique(np.asarray(ids, np.int64))
    if idx.size == 0:
        return ""
    breaks = np.flatnonzero(np.diff(idx) != 1)
    starts = np.concatenate([idx[:1], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], idx[-1:]])
    return " ".join(f"{a}:{b}" if a != b else f"{a}" for a, b in zip(starts.tolist(), ends.tolist()))


# ----------------------------------------------------------------------------- writing


def write_data_file(path: str | Path, box_lo, box_hi, x, mass, *, v=None, radius=None, shape=None, quat=None,
                    angmom=None, types=None, image=None, title: str = "written by wallbatch") -> Path:
    """Write atoms as a LAMMPS data file (shortest round-trip decimals, so every double reads back
    exactly): atom_style ellipsoid when `shape` is given (diameters in the file), sphere when
    `radius` has a value > 0, else atomic. Atom IDs are 1..N in order. The per-atom mass is the
    type mass (atomic; one type per distinct mass unless `types` is given) or the density that
    gives it back (sphere, ellipsoid; exact up to the rounding of density * volume)."""
    x = np.asarray(x, float)
    n = len(x)
    mass = np.broadcast_to(np.asarray(mass, float), (n,))
    ids = np.arange(1, n + 1)
    if types is None:
        _masses, inv = np.unique(mass, return_inverse=True)
        types = inv.astype(np.int64) + 1
    types = np.asarray(types, np.int64)
    image = np.zeros((n, 3), np.int64) if image is None else np.asarray(image, np.int64)
    style = "ellipsoid" if shape is not None else ("sphere" if radius is not None and np.any(np.asarray(radius) > 0)
                                                   else "atomic")
    r = lambda *cols: [" ".join(repr(c) if isinstance(c, float) else str(c) for c in row)
                       for row in zip(*(np.asarray(col).tolist() for col in cols))]
    ntypes = int(types.max()) if n else 1
    head = [title, "", f"{n} atoms", f"{ntypes} atom types"]
    sections: list[tuple[str, list[str]]] = []
    if style == "atomic":
        tm = {}
        for t, m in zip(types.tolist(), mass.tolist()):
            if tm.setdefault(t, m) != m:
                raise ValueError(f"atom type {t} has two masses: atomic data files hold one mass per type")
        sections.append(("Masses", [f"{t} {tm.get(t, 1.0)!r}" for t in range(1, ntypes + 1)]))
        sections.append(("Atoms # atomic", r(ids, types, x[:, 0], x[:, 1], x[:, 2], *image.T)))
        vcols = []
    elif style == "sphere":
        rad = np.broadcast_to(np.asarray(radius, float), (n,))
        density = np.where(rad > 0, mass / np.where(rad > 0, _FOUR_PI_3 * rad ** 3, 1.0), mass)
        sections.append(("Atoms # sphere", r(ids, types, 2.0 * rad, density, x[:, 0], x[:, 1], x[:, 2], *image.T)))
        vcols = [np.zeros(n)] * 3
    else:
        shp = np.asarray(shape, float).reshape(n, 3)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if quat is None else np.asarray(quat, float).reshape(n, 4)
        ell = np.all(shp > 0, axis=1)
        vol = _FOUR_PI_3 * np.prod(np.where(ell[:, None], shp, 1.0), axis=1)
        density = np.where(ell, mass / vol, mass)
        head.append(f"{int(ell.sum())} ellipsoids")
        sections.append(("Atoms # ellipsoid", r(ids, types, ell.astype(np.int64), density, x[:, 0], x[:, 1], x[:, 2],
                                                *image.T)))
        sections.append(("Ellipsoids", r(ids[ell], *(2.0 * shp[ell].T), *q[ell].T)))
        L = np.zeros((n, 3)) if angmom is None else np.asarray(angmom, float).reshape(n, 3)
        vcols = list(L.T)
    head.append("")
    lo, hi = np.asarray(box_lo, float), np.asarray(box_hi, float)
    head += [f"{float(lo[d])!r} {float(hi[d])!r} {a}lo {a}hi" for d, a in enumerate("xyz")]
    if v is not None:
        vv = np.asarray(v, float).reshape(n, 3)
        sections.append(("Velocities", r(ids, vv[:, 0], vv[:, 1], vv[:, 2], *vcols)))
    out = list(head)
    for header, rows in sections:
        out += ["", header, ""] + rows
    path = Path(path)
    path.write_text("\n".join(out) + "\n")
    return path
