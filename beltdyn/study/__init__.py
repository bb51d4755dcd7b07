"""Studies that run many analyses: sweeps with mode tracking, the paper's tables. See
docs/architecture.md.
"""
