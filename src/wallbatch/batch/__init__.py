"""Running plans: batching cases, local and dask executors, per-case parts and resume.

May import: wallbatch.io, wallbatch.engine and everything below them.
"""
