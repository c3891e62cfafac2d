"""The config language: YAML with line marks, Pydantic models, cross-field checks, fix lines, sweeps, JSON schema.

May import: wallbatch.styles, wallbatch.geometry and the leaves (units, expr).
"""
