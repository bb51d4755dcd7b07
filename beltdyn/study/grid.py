"""The sweep's parameter grid: parameters (dotted keys with value lists), combined as a grid (C order, the
last parameter fastest) or zipped (`SweepSpec`); the values read from a command line spec (`parse_values`);
each case's overrides of the base configuration (`case_assignments`) and the sweep's identity (`spec_hash`).
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from beltdyn.config import DriveConfig, config_hash
from beltdyn.errors import ConfigError

ANALYSES = ("static", "modal", "transient")


@dataclass(frozen=True, kw_only=True)
class Param:
    key: str
    values: tuple[Any, ...]


@dataclass(frozen=True, kw_only=True)
class SweepSpec:
    params: tuple[Param, ...]
    analysis: str
    zip: bool
    n_modes: int

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.params[0].values),) if self.zip else tuple(len(p.values) for p in self.params)

    @property
    def n_cases(self) -> int:
        return int(np.prod(self.shape))

    def case_values(self, index: int) -> tuple[Any, ...]:
        if self.zip:
            return tuple(p.values[index] for p in self.params)
        multi = np.unravel_index(index, self.shape)
        return tuple(p.values[int(i)] for p, i in zip(self.params, multi))

    def parent(self, index: int) -> int:
        """Neighbour one step back along the last axis that moved; -1 for the first case."""
        if index == 0:
            return -1
        if self.zip:
            return index - 1
        multi = list(np.unravel_index(index, self.shape))
        for axis in range(len(multi) - 1, -1, -1):
            if multi[axis] > 0:
                multi[axis] -= 1
                return int(np.ravel_multi_index(multi, self.shape))
        return -1

    def parents(self) -> np.ndarray:
        """`parent` of every case, as an array."""
        n = self.n_cases
        idx = np.arange(n, dtype=np.int64)
        if self.zip:
            return idx - 1
        out = np.full(n, -1, dtype=np.int64)
        multi = np.unravel_index(idx, self.shape)
        stride = 1
        todo = idx > 0
        for axis in range(len(self.shape) - 1, -1, -1):
            hit = todo & (multi[axis] > 0)
            out[hit] = idx[hit] - stride
            todo &= ~hit
            stride *= self.shape[axis]
        return out

    def to_json(self) -> dict:
        return {"params": [{"key": p.key, "values": list(p.values)} for p in self.params],
                "analysis": self.analysis, "zip": self.zip, "n_modes": self.n_modes}


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_values(key: str, spec: str, *, where: str = "--param") -> tuple[Any, ...]:
    """'0.02,1,100' (list), '100:600:26' (26 values from 100 to 600), '0.02:100:9:log' (log-spaced)."""
    spec = spec.strip()
    m = re.fullmatch(rf"({_NUM}):({_NUM}):(\d+)(?::(lin|log))?", spec)
    if m:
        a, b, n, kind = float(m.group(1)), float(m.group(2)), int(m.group(3)), m.group(4) or "lin"
        if n < 1:
            raise ConfigError("a range needs at least 1 value", key=f"{where} {key}={spec}")
        if kind == "log":
            if a <= 0 or b <= 0:
                raise ConfigError("a log range needs positive bounds", key=f"{where} {key}={spec}")
            vals = np.geomspace(a, b, n)
        else:
            vals = np.linspace(a, b, n)
        if key.endswith("elements_per_span"):
            return tuple(int(round(v)) for v in vals)
        return tuple(float(v) for v in vals)
    import tomllib

    out = []
    for item in spec.split(","):
        item = item.strip()
        if not item:
            raise ConfigError("empty value in the list", key=f"{where} {key}={spec}")
        try:
            out.append(tomllib.loads(f"v = {item}")["v"])
        except tomllib.TOMLDecodeError:
            if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", item):
                out.append(item)
            else:
                raise ConfigError(f"'{item}' is not a TOML literal", key=f"{where} {key}={spec}") from None
    return tuple(out)


def make_spec(cfg: DriveConfig, params: list[tuple[str, str]], *, analysis: str, zip_: bool,
              n_modes: int | None = None) -> SweepSpec:
    """Validate the sweep: zipped, equal lengths; every case a valid configuration (`_check_cases`)."""
    if analysis not in ANALYSES:
        raise ConfigError(f"must be one of {', '.join(ANALYSES)}, got {analysis!r}", file=cfg.source, key="--analysis")
    if not params:
        raise ConfigError("give at least one --param KEY=SPEC (or a [sweep] table)", file=cfg.source, key="--param")
    ps = tuple(Param(key=k, values=parse_values(k, v)) for k, v in params)
    keys = [p.key for p in ps]
    if len(set(keys)) != len(keys):
        raise ConfigError("a key is swept twice", file=cfg.source, key="--param")
    if zip_ and len({len(p.values) for p in ps}) > 1:
        raise ConfigError("--zip needs value lists of equal length: "
                          + ", ".join(f"{p.key} has {len(p.values)}" for p in ps), file=cfg.source, key="--param")
    if analysis == "transient" and cfg.transient is None:
        raise ConfigError("a transient sweep needs a [transient] table", file=cfg.source, key="transient")
    spec = SweepSpec(params=ps, analysis=analysis, zip=zip_, n_modes=n_modes or cfg.modal.modes)
    _check_cases(cfg, spec)
    return spec


def merge_params(table: tuple[tuple[str, str], ...] | list[tuple[str, str]],
                 given: list[tuple[str, str]]) -> tuple[list[tuple[str, str]], tuple[str, ...]]:
    """The swept parameters and the keys the command line overrode (issue 26): the file's [sweep.params]
    (`table`) with the command line's --param (`given`) applied key by key. A key in both takes the
    command line's spec, in the file's place; a key only on the command line is appended, in its order."""
    merged = list(table)
    at = {k: i for i, (k, _) in enumerate(merged)}
    overridden = []
    for k, v in given:
        if k in at:
            merged[at[k]] = (k, v)
            overridden.append(k)
        else:
            merged.append((k, v))
    return merged, tuple(overridden)


CHECK_EVERY_CASE = 5000  # larger grids: every value of every parameter (the others at their first value)


def _check_cases(cfg: DriveConfig, spec: SweepSpec) -> None:
    """Every case must be a valid configuration (ConfigError naming the key and the case before any
    case runs); cheap (~0.1 ms a case). Grids of more than CHECK_EVERY_CASE cases are checked value by
    value. A transient sweep measures its amplitudes after transient.spectrum.start, so that must
    come before transient.duration in every case, whether or not the spectrum is enabled."""
    import copy

    from beltdyn.config import apply_override, config_from_dict, config_to_dict

    raw = config_to_dict(cfg)
    tables = sweep_tables(cfg, spec)
    if spec.zip or spec.n_cases <= CHECK_EVERY_CASE:
        cases = [spec.case_values(i) for i in range(spec.n_cases)]
    else:
        first = [p.values[0] for p in spec.params]
        cases = [tuple(v if k == j else first[k] for k in range(len(spec.params)))
                 for j, p in enumerate(spec.params) for v in p.values]
    seen = set()
    for values in cases:
        assignments = case_assignments(spec, values, tables)
        marker = tuple(assignments)
        if marker in seen:
            continue
        seen.add(marker)
        where = ", ".join(assignments)
        case_raw = copy.deepcopy(raw)
        try:
            for a in assignments:
                apply_override(case_raw, a, file=cfg.source)
            c = config_from_dict(case_raw, file=cfg.source)
            from beltdyn.model.system import check_model_size

            check_model_size(c)
        except ConfigError as exc:
            raise ConfigError(f"{exc.detail} (in the sweep case {where})", file=exc.file, key=exc.key) from None
        if spec.analysis == "transient" and c.transient is not None \
                and not c.transient.spectrum.start < c.transient.duration:
            raise ConfigError(f"must be < transient.duration ({c.transient.duration:g} s) in every case of a "
                              f"transient sweep (the amplitudes are measured after it), got "
                              f"{c.transient.spectrum.start:g} (in the sweep case {where})",
                              file=cfg.source, key="transient.spectrum.start")


def _assign(key: str, value: Any) -> str:
    import tomli_w

    text = tomli_w.dumps({"v": value}).strip()[len("v = "):]
    return f"{key}={text}"


def case_assignments(spec: SweepSpec, values: tuple, tables: dict[str, bytes]) -> list[str]:
    """The overrides of one case. A swept table file (a key ending in .table) also sets its
    table_sha256 to that file's (`tables`, from `sweep_tables`), in place of the one the base
    configuration resolved for its own table: every case is held to the table version swept."""
    out = []
    for p, v in zip(spec.params, values):
        out.append(_assign(p.key, v))
        if p.key.endswith(".table"):
            out.append(_assign(f"{p.key}_sha256", hashlib.sha256(tables[str(v)]).hexdigest()))
    return out


def sweep_tables(cfg: DriveConfig, spec: SweepSpec) -> dict[str, bytes]:
    """The bytes of every CSV table the sweep's cases read (the configuration's and every swept table
    value), sent with the cases to the workers (`run_case`)."""
    from beltdyn.config import table_bytes

    swept = tuple(str(v) for p in spec.params if p.key.endswith(".table") for v in p.values)
    try:
        return table_bytes(cfg, swept)
    except OSError as exc:  # (the cases' check read them a moment ago)
        raise ConfigError(f"cannot read a table: {exc}", file=cfg.source, key="--param") from None


def spec_hash(cfg: DriveConfig, spec: SweepSpec) -> str:
    """The sweep's identity (a journal resumes only the same one): the configuration (its tables'
    sha256 included), the grid, and the sha256 of every swept table file."""
    tables = sweep_tables(cfg, spec)
    swept = {str(v): hashlib.sha256(tables[str(v)]).hexdigest()
             for p in spec.params if p.key.endswith(".table") for v in p.values}
    return hashlib.sha256((config_hash(cfg) + json.dumps(spec.to_json(), sort_keys=True)
                           + json.dumps(swept, sort_keys=True)).encode()).hexdigest()
