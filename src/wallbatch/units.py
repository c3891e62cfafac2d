"""LAMMPS unit systems (physics.md §2) and lattice spacings (§2.1).

`ftm2v` turns force/mass into velocity/time (a = ftm2v F/m), `mvv2e` turns mass*velocity^2 into
energy (KE = 1/2 mvv2e m v^2), `boltz` is k_B in energy per temperature unit.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class UnitSystem:
    name: str
    boltz: float
    mvv2e: float
    ftm2v: float
    dt: float  # LAMMPS default timestep
    # unit labels of the output quantities (CF `units` attribute)
    energy: str
    distance: str
    time: str
    temperature: str
    force: str
    pressure: str
    velocity: str
    mass: str
    nktv2p: float = 1.0  # pressure from energy/volume (LAMMPS force->nktv2p)


UNIT_SYSTEMS: dict[str, UnitSystem] = {
    "lj": UnitSystem("lj", 1.0, 1.0, 1.0, 0.005, "1", "1", "1", "1", "1", "1", "1", "1"),
    "real": UnitSystem(
        "real", 0.0019872067, 48.88821291 * 48.88821291, 1.0 / 48.88821291 / 48.88821291, 1.0,
        "kcal/mol", "Angstrom", "fs", "K", "kcal/mol/Angstrom", "atm", "Angstrom/fs", "g/mol", 68568.415,
    ),
    "metal": UnitSystem(
        "metal", 8.617343e-5, 1.0364269e-4, 1.0 / 1.0364269e-4, 0.001,
        "eV", "Angstrom", "ps", "K", "eV/Angstrom", "bar", "Angstrom/ps", "g/mol", 1.6021765e6,
    ),
}

# basis atoms per unit cell (V_prim = 1 for sc, bcc, fcc, sq, sq2; the area sqrt(3) for hex)
LATTICE_BASIS = {"sc": 1, "bcc": 2, "fcc": 4, "sq": 1, "sq2": 2, "hex": 2}
LATTICES_2D = ("sq", "sq2", "hex")
# unit-cell edges in units of the lattice constant a (hex: a2 = (0, sqrt(3), 0))
LATTICE_CELL = {"hex": (1.0, 3.0 ** 0.5, 1.0)}

# unit-cell basis positions in lattice units, for `create: {lattice: ...}`
LATTICE_POSITIONS = {
    "sc": [(0.0, 0.0, 0.0)],
    "bcc": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.5)],
    "fcc": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5)],
    "sq": [(0.0, 0.0, 0.0)],
    "sq2": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0)],
    "hex": [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0)],
}


def lattice_constant(style: str, scale: float, units: str) -> float:
    """Lattice constant a [distance]: in lj units `scale` is the reduced density rho*, so
    a = (n_basis / rho*)^(1/3) in 3-D and (n_basis / (V_prim rho*))^(1/2) for the 2-D lattices
    sq, sq2, hex (V_prim = sqrt(3) for hex); in other units `scale` is a itself."""
    if units == "lj":
        if style in LATTICES_2D:
            area = 3.0 ** 0.5 if style == "hex" else 1.0
            return (LATTICE_BASIS[style] / (area * scale)) ** 0.5
        return (LATTICE_BASIS[style] / scale) ** (1.0 / 3.0)
    return float(scale)
