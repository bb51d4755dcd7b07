"""Measured natural frequencies (a CSV file) for `beltdyn fit`: reading and validation.

One row per measured mode. Columns (a header line first; lines starting with '#' are comments):
- `frequency` (Hz, > 0, required);
- `kind` (one of the modal kinds: transverse, longitudinal, rotational, translational, tensioner,
  mixed), `order` (integer >= 1: the half-wave count of a transverse mode, the rank within its kind
  otherwise), `span` (1-based span number): pair the row with the computed mode of that
  classification; without `kind` the row pairs with the nearest computed mode (one to one);
- `weight` (> 0, default 1): the row's weight in the least squares (its squared relative residual
  is multiplied by it);
- `scatter` (Hz, > 0, default 1 % of the frequency): the measurement's scatter; two computed modes
  within it of an unclassified row make its pairing ambiguous (a warning);
- `reference` (Hz, optional): a value printed beside the row (e.g. a published theoretical value),
  not used by the fit;
- any dotted configuration key (`tension.target`, `running.driver_speed`, ...): that row's load case
  (a TOML literal, as `--set KEY=VALUE`); the rows with equal values form one case, compared with one
  analysis of it. A key left empty in a row takes the configuration's value.

Errors name the file, the row (the line number in the file) and the column (exit 2).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beltdyn.config import DriveConfig, with_overrides
from beltdyn.errors import ConfigError
from beltdyn.model.components import ENERGY_KINDS

KINDS = tuple(ENERGY_KINDS) + ("mixed",)
OWN_COLUMNS = ("frequency", "kind", "order", "span", "weight", "scatter", "reference")
DEFAULT_SCATTER = 0.01  # relative: the scatter of a row that gives none


@dataclass(frozen=True, kw_only=True)
class MeasuredData:
    """Measured frequencies, m rows. kind "" / order 0 / span 0: not given."""

    file: str
    line: np.ndarray  # (m,) int, line number of each row in the file (1-based), for messages
    frequency: np.ndarray  # (m,) Hz
    kind: tuple[str, ...]  # (m,)
    order: np.ndarray  # (m,) int, 0: not given
    span: np.ndarray  # (m,) int, 0: not given
    weight: np.ndarray  # (m,)
    scatter: np.ndarray  # (m,) Hz
    reference: np.ndarray  # (m,) Hz, NaN where not given
    case_keys: tuple[str, ...]  # the dotted keys that set the load cases (columns)
    case: np.ndarray  # (m,) int, the load case of each row (index into `cases`)
    cases: tuple[tuple[str, ...], ...]  # per case, its overrides "key=value" (empty: the configuration as given)

    @property
    def n_rows(self) -> int:
        return len(self.frequency)

    def case_name(self, c: int) -> str:
        """A load case in words: its overrides, or "as configured"."""
        return ", ".join(self.cases[c]) or "as configured"


def _fail(file: str, line: int, column: str, message: str) -> ConfigError:
    return ConfigError(message, file=file, key=f"row {line}, column '{column}'")


def _number(file: str, line: int, column: str, text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise _fail(file, line, column, f"must be a number, got {text!r}") from None
    if not math.isfinite(x):
        raise _fail(file, line, column, f"must be finite, got {text!r}")
    return x


def _positive_int(file: str, line: int, column: str, text: str) -> int:
    x = _number(file, line, column, text)
    if x != int(x) or x < 1:
        raise _fail(file, line, column, f"must be an integer >= 1, got {text!r}")
    return int(x)


def read_measured(path: Path | str) -> MeasuredData:
    """Read and check a measured-frequency CSV (module docstring). ConfigError (exit 2) naming the
    file, row and column of the first defect; the key columns are checked against a configuration by
    `check_cases`."""
    file = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise ConfigError(f"cannot read the measured file: {exc.strerror or exc}", file=file,
                          key="--measured") from None
    lines = [(i + 1, s) for i, s in enumerate(text.splitlines()) if s.strip() and not s.lstrip().startswith("#")]
    if not lines:
        raise ConfigError("no header and no rows", file=file, key="--measured")
    rows = list(csv.reader([s for _, s in lines], skipinitialspace=True))
    header = [h.strip() for h in rows[0]]
    head_line = lines[0][0]
    for j, h in enumerate(header):
        if not h:
            raise _fail(file, head_line, f"#{j + 1}", "empty column name")
        if h in header[:j]:
            raise _fail(file, head_line, h, "column given twice")
    if "frequency" not in header:
        raise ConfigError(f"no 'frequency' column (columns: {', '.join(header)})", file=file,
                          key=f"row {head_line}, column 'frequency'")
    keys = tuple(h for h in header if h not in OWN_COLUMNS)
    for h in keys:
        if "." not in h:  # a dotted configuration key, or a column of ours misspelt
            raise _fail(file, head_line, h, f"unknown column: not one of {', '.join(OWN_COLUMNS)} nor a dotted "
                                            f"configuration key")
    if len(rows) < 2:
        raise ConfigError("no measured rows", file=file, key="--measured")
    out: dict[str, list] = {c: [] for c in OWN_COLUMNS}
    line_no, case_of, cases = [], [], {}
    for (ln, _), row in zip(lines[1:], rows[1:]):
        if len(row) != len(header):
            raise _fail(file, ln, header[min(len(row), len(header) - 1)],
                        f"{len(row)} values for {len(header)} columns")
        cell = {h: v.strip() for h, v in zip(header, row)}
        f = _number(file, ln, "frequency", cell["frequency"])
        if f <= 0.0:
            raise _fail(file, ln, "frequency", f"must be > 0 Hz, got {cell['frequency']}")
        kind = cell.get("kind", "")
        if kind and kind not in KINDS:
            raise _fail(file, ln, "kind", f"unknown kind {kind!r}; one of {', '.join(KINDS)}")
        order = _positive_int(file, ln, "order", cell["order"]) if cell.get("order") else 0
        span = _positive_int(file, ln, "span", cell["span"]) if cell.get("span") else 0
        if (order or span) and not kind:
            raise _fail(file, ln, "order" if order else "span", "an order or span needs a kind")
        weight = _number(file, ln, "weight", cell["weight"]) if cell.get("weight") else 1.0
        if weight <= 0.0:
            raise _fail(file, ln, "weight", f"must be > 0, got {cell['weight']}")
        scatter = _number(file, ln, "scatter", cell["scatter"]) if cell.get("scatter") else DEFAULT_SCATTER * f
        if scatter <= 0.0:
            raise _fail(file, ln, "scatter", f"must be > 0 Hz, got {cell['scatter']}")
        reference = _number(file, ln, "reference", cell["reference"]) if cell.get("reference") else math.nan
        case = tuple(f"{k}={cell[k]}" for k in keys if cell[k])
        for name, value in zip(OWN_COLUMNS, (f, kind, order, span, weight, scatter, reference)):
            out[name].append(value)
        line_no.append(ln)
        case_of.append(cases.setdefault(case, len(cases)))
    return MeasuredData(file=file, line=np.array(line_no, dtype=np.int64), frequency=np.array(out["frequency"]),
                        kind=tuple(out["kind"]), order=np.array(out["order"], dtype=np.int64),
                        span=np.array(out["span"], dtype=np.int64), weight=np.array(out["weight"]),
                        scatter=np.array(out["scatter"]), reference=np.array(out["reference"]), case_keys=keys,
                        case=np.array(case_of, dtype=np.int64), cases=tuple(cases))


def check_cases(cfg: DriveConfig, data: MeasuredData) -> tuple[DriveConfig, ...]:
    """The configuration of each load case (cfg with the case's overrides); a key the configuration
    does not have, or a value it refuses, is a ConfigError naming the measured file, the first row of
    that case and the column."""
    out = []
    for c, overrides in enumerate(data.cases):
        line = int(data.line[np.flatnonzero(data.case == c)[0]])
        for a in overrides:  # each key alone first: the column at fault is named
            try:
                with_overrides(cfg, [a])
            except ConfigError as exc:
                raise _fail(data.file, line, a.split("=", 1)[0], exc.detail) from None
        try:
            out.append(with_overrides(cfg, list(overrides)))
        except ConfigError as exc:
            raise _fail(data.file, line, ", ".join(data.case_keys), exc.detail) from None
    return tuple(out)


__all__ = ["DEFAULT_SCATTER", "KINDS", "OWN_COLUMNS", "MeasuredData", "check_cases", "read_measured"]
