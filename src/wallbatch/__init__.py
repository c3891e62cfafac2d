"""wallbatch: batches of particle simulations bounded by LAMMPS-style walls."""

__version__ = "0.1.0"
