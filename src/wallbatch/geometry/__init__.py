"""Geometry: region shapes (block, sphere, cylinder) and quaternion/ellipsoid mathematics.

May import: numpy and the leaves (wallbatch.units, wallbatch.expr); nothing else of wallbatch.
"""
