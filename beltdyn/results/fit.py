"""The `/fit` group of `beltdyn fit`: a `study.fit.FitResult` as the results layer's `GroupData`
(like `results.export` does for the other groups; no h5py here).

Axes: `parameter` (n, the dotted keys), `parameter_j` (the same keys, the correlation matrix's second
axis) and `measurement` (m, the measured rows in file order).
"""

from __future__ import annotations

import numpy as np

from beltdyn.results.export import param_units
from beltdyn.results.io import GroupData, Variable


def fit_group(result) -> GroupData:
    """/fit of a `study.fit.FitResult` (taken by its fields: the results layer does not import the
    studies above it)."""
    keys = list(result.keys)
    units = [param_units(k) for k in keys]
    unit = units[0] if len(set(units)) == 1 else "see parameter_unit"
    par = ("parameter",)
    row = ("measurement",)
    variables = (
        Variable(name="parameter_unit", data=units, dims=par, units="1", description="unit of each parameter"),
        Variable(name="initial", data=np.asarray(result.initial), dims=par, units=unit,
                 description="initial value (the configuration's)"),
        Variable(name="fitted", data=np.asarray(result.fitted), dims=par, units=unit,
                 description="identified value (the initial one where not identifiable)"),
        Variable(name="standard_deviation", data=np.asarray(result.std), dims=par, units=unit,
                 description="sqrt(diag(s^2 (J^T J)^-1)) at the solution, linearized; NaN where not identifiable "
                             "or without redundancy"),
        Variable(name="lower_bound", data=np.asarray(result.lower), dims=par, units=unit, description="lower bound"),
        Variable(name="upper_bound", data=np.asarray(result.upper), dims=par, units=unit, description="upper bound"),
        Variable(name="identifiable", data=np.asarray(result.identifiable, dtype=np.int8), dims=par, units="1",
                 description="1: fitted; 0: the measurements do not determine it (held at its initial value)"),
        Variable(name="sensitivity_method", data=list(result.method), dims=par, units="1",
                 description="modal: from the eigenvectors at a fixed state; analyses: central differences of "
                             "whole analyses (the parameter moves the equilibrium)"),
        Variable(name="correlation", data=np.asarray(result.correlation), dims=("parameter", "parameter_j"),
                 units="1", description="correlation matrix of the fitted parameters (NaN for the others)"),
        Variable(name="measured_frequency", data=np.asarray(result.measured), dims=row, units="Hz",
                 description="measured natural frequency"),
        Variable(name="weight", data=np.asarray(result.weight), dims=row, units="1",
                 description="weight of the row's squared relative residual"),
        Variable(name="reference_frequency", data=np.asarray(result.reference), dims=row, units="Hz",
                 description="the file's reference column (e.g. a published theoretical value), NaN if none"),
        Variable(name="file_line", data=np.asarray(result.row_line, dtype=np.int64), dims=row, units="1",
                 description="line of the row in the measured file"),
        Variable(name="load_case", data=[result.cases[int(c)] for c in result.case], dims=row, units="1",
                 description="the row's load case (its overrides)"),
        Variable(name="mode_label", data=list(result.mode_label), dims=row, units="1",
                 description="the computed mode the row is paired with"),
        Variable(name="frequency_before", data=np.asarray(result.before), dims=row, units="Hz",
                 description="computed at the initial parameters"),
        Variable(name="frequency_after", data=np.asarray(result.after), dims=row, units="Hz",
                 description="computed at the fitted parameters"),
    )
    return GroupData(
        name="fit",
        coords={"parameter": keys, "parameter_j": keys, "measurement": np.arange(len(result.measured))},
        coord_units={"parameter": "1", "parameter_j": "1", "measurement": "1"},
        variables=variables,
        attrs={"rms_relative_error_before": float(result.rms_before),
               "rms_relative_error_after": float(result.rms_after),
               "residual_variance": float(result.residual_variance),
               "evaluations": int(result.evaluations), "optimizer_status": str(result.status),
               "measured_file": str(result.measured_file), "warnings": list(result.warnings),
               "residuals": "sqrt(weight) (computed - measured) / measured"},
    )


__all__ = ["fit_group"]
