"""Frozen dataclasses made fast: an instance of every field at once (the small models' hot paths)."""

from __future__ import annotations


def set_at_once(cls, **fields):
    """An instance of the frozen dataclass `cls` from every one of its fields (no default filled in), set at
    once: the dataclass's __init__ sets them one by one through object.__setattr__ (17 calls a `Layout`).
    Tests hold a layout and the objects of a build to every field of their class, nothing else
    (tests/test_geometry_checks.py, tests/test_system.py)."""
    obj = object.__new__(cls)
    obj.__dict__.update(fields)
    return obj
