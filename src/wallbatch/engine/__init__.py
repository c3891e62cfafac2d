"""The batched engine: state, fixes (walls, reflect, flow), integrators, pair forces, minimize, compiled path.

May import: wallbatch.scene and everything below it (config, styles, geometry, leaves).
"""
