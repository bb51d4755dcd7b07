"""beltdyn: dynamics of belt drives with ANCF belt spans on rigid pulleys.

Data flow: TOML -> config -> geometry -> model -> analysis -> result -> HDF5 (results_io).
Heavy modules (scipy, h5py) are imported lazily by the modules that need them.
"""

__version__ = "0.1.0"
SCHEMA_VERSION = "1"
