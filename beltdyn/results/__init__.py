"""Result files: the HDF5 schema, atomic writes, streams, journals, locks, recovery, and the export
of result objects into groups. See docs/architecture.md.
"""
