"""Scenes: a `Case` (frozen arrays and specs in box units), its builder from a config, the batching key.

May import: wallbatch.config, wallbatch.styles, wallbatch.geometry and the leaves.
"""
