"""Storage and reading of results: NetCDF results, AMBER trajectories, the report accessor and plots.

May import: wallbatch.engine and everything below it.
"""
