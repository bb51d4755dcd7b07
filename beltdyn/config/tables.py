"""The CSV load tables a configuration names: read next to the configuration file (or from the
bytes a sweep worker is given, `table_bytes`), checked with the key path."""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

from beltdyn.config.kinds import _Checker
from beltdyn.config.schema import DriveConfig


def table_bytes(cfg: DriveConfig, names: tuple[str, ...] = ()) -> dict[str, bytes]:
    """The bytes of every CSV table the configuration reads, and of the tables `names` (a sweep's other
    table values), by the name it gives them (read next to cfg.source now; the sha256 check on
    parsing still holds them to the configuration's version)."""
    wanted = [load.signals[0].table for load in cfg.transient.loads] if cfg.transient is not None else []
    base = Path(cfg.source).parent if cfg.source and not cfg.source.startswith("<") else Path(".")
    out: dict[str, bytes] = {}
    for name in [*wanted, *names]:
        if name and name not in out:
            out[name] = ((base / name) if not Path(name).is_absolute() else Path(name)).read_bytes()
    return out


def _read_table(chk: _Checker, key: str, name: str, file: str, n_values: int,
                expect_sha: str = "") -> tuple[str, tuple[tuple, ...]]:
    """CSV (comma or whitespace separated, '#' comments): time, value(s); path relative to the config.
    Returns the sha256 of the file's bytes and the columns; expect_sha (from a resolved configuration)
    must match, so results never mix two versions of a table."""
    base = Path(file).parent if file and not file.startswith("<") else Path(".")
    path = (base / name) if not Path(name).is_absolute() else Path(name)
    try:
        data = chk.tables[name] if name in chk.tables else path.read_bytes()
        lines = data.decode("utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise chk.fail(key, f"cannot read table '{name}': {getattr(exc, 'strerror', None) or exc}") from None
    sha = hashlib.sha256(data).hexdigest()
    if expect_sha and expect_sha != sha:
        raise chk.fail(key, f"table '{name}' changed since this configuration was resolved (sha256 differs)")
    rows = []
    for i, line in enumerate(lines, 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p for p in re.split(r"[,\s;]+", line) if p]
        vals = [_float_or_none(p) for p in parts]
        if None in vals:
            if not rows and all(v is None for v in vals):  # a header line: no number in it
                continue
            raise chk.fail(key, f"table '{name}' line {i}: not numbers: {line!r}")
        if len(vals) != 1 + n_values or not all(math.isfinite(v) for v in vals):
            raise chk.fail(key, f"table '{name}' line {i}: expected {1 + n_values} finite numbers (time, "
                                f"value{'s' if n_values > 1 else ''}), got {line!r}")
        rows.append(vals)
    if len(rows) < 2:
        raise chk.fail(key, f"table '{name}' needs at least 2 rows")
    cols = tuple(zip(*rows))
    if any(b <= a for a, b in zip(cols[0], cols[0][1:])):
        raise chk.fail(key, f"table '{name}': times must increase")
    return sha, cols


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None
