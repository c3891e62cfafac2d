"""LAMMPS interop: export of a case as a LAMMPS input, validation against LAMMPS, the LAMMPS log reader.

May import: wallbatch.batch, wallbatch.io, wallbatch.engine and everything below them.
"""
