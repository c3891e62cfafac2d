import os
import sys

# Make helper modules in tests/ (e.g. lammps_oracle) importable from any test.
_TESTS_DIR = os.path.dirname(os.path.abspath(__file__))
if _TESTS_DIR not in sys.path:
    sys.path.insert(0, _TESTS_DIR)
