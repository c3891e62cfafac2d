"""Wall potential styles: pure energy/force functions and their registry (one entry per style).

May import: numpy, wallbatch.geometry and the leaves (units, expr).
"""
