"""What a results file holds, read once for the figures and the report; the figures a file can give;
the names of the figure files a `beltdyn plot` run writes."""

from __future__ import annotations

import itertools
import json
import tomllib
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import h5py
import numpy as np

from beltdyn.errors import OutputError
from beltdyn.results.io import read_group, read_root_attrs

SLIP_CAP = 1e6  # slip margins above this (torque-free pulleys: ~1e12 or inf) are left out of panels and tables
KINDS = ("layout", "modes", "sweep", "transient", "response", "fit")
NEEDS = MappingProxyType({  # figure -> (groups it reads, the command that writes the first)
    "layout": (("geometry",), "beltdyn geometry (or static, modal)"),
    "modes": (("static", "modal"), "beltdyn modal"),
    "sweep": (("sweep",), "beltdyn sweep"),
    "transient": (("transient",), "beltdyn transient"),
    "response": (("response",), "beltdyn response"),
    "fit": (("fit",), "beltdyn fit --measured MEASURED.csv --param KEY"),
})


@dataclass(frozen=True, kw_only=True)
class Results:
    """What a results file holds, read once: groups by name (`results.io.read_group` dicts), the
    configuration (the parsed provenance TOML, a dict), its text, and the root attributes."""

    path: Path
    groups: MappingProxyType
    config: MappingProxyType
    config_text: str
    attrs: MappingProxyType

    def has(self, name: str) -> bool:
        return name in self.groups and self.groups[name]["attrs"].get("status", "complete") == "complete"

    def var(self, group: str, name: str) -> np.ndarray:
        return np.asarray(self.groups[group]["variables"][name])

    def holds(self, group: str, name: str) -> bool:
        return group in self.groups and name in self.groups[group]["variables"]

    def coord(self, group: str, name: str):
        return self.groups[group]["coords"][name]

    @property
    def title(self) -> str:
        return str(self.config.get("title", "") or self.path.stem)


def read_results(path: Path) -> Results:
    """Every group of a beltdyn results file (OutputError, exit 2, for a missing, unreadable or foreign
    file)."""
    path = Path(path)
    if not path.exists():
        raise OutputError(f"{path}: no such results file (make one with beltdyn geometry/static/modal/transient/"
                          f"sweep/response CONFIG -o {path})")
    try:
        with h5py.File(path, "r") as f:
            names = [k for k, v in f.items() if isinstance(v, h5py.Group) and k != "provenance"]
            toml = f["provenance/config_toml"][()] if "provenance/config_toml" in f else b""
            subs = [f"transient/{k}" for k in ("spectrum", "peaks") if f"transient/{k}" in f]
    except OSError as exc:
        raise OutputError(f"{path}: not a readable HDF5 results file ({exc})") from None
    attrs = read_root_attrs(path)
    groups = {name: read_group(path, name) for name in names + subs}
    text = toml.decode() if isinstance(toml, bytes) else str(toml)
    try:
        config = tomllib.loads(text) if text else {}
    except tomllib.TOMLDecodeError:
        config = {}
    return Results(path=path, groups=MappingProxyType(groups), config=MappingProxyType(config), config_text=text,
                   attrs=MappingProxyType(dict(attrs)))


def available(res: Results) -> tuple[str, ...]:
    """The figures the file can give, in KINDS order."""
    return tuple(k for k in KINDS if all(res.has(g) for g in NEEDS[k][0]))


def require(res: Results, kind: str) -> None:
    """OutputError (exit 2) naming the missing groups and the command, with the file's own path, that
    makes them."""
    groups, command = NEEDS[kind]
    missing = [g for g in groups if not res.has(g)]
    if missing:
        raise OutputError(f"{res.path}: the {kind} figure needs /{' and /'.join(missing)}, which this file does "
                          f"not hold (complete){_running(res, missing)}; make it with {command} CONFIG -o "
                          f"{res.path}")


def _running(res: Results, names: list[str]) -> str:
    """What a missing group is doing if it is marked running: written now, or left so by a dead writer."""
    for name in names:
        writer = res.groups.get(name, {}).get("writer")
        if writer is None:
            continue
        if writer["alive"] is False:
            return (f" (/{name} is marked running, but its writer, pid {writer['pid']} on {writer['host']}, no longer "
                    "runs: the next beltdyn command writing this file recovers its samples)")
        return f" (/{name} is being written by pid {writer['pid']} on {writer['host']})"
    return ""


def figure_paths(result: Path, kinds: tuple[str, ...], *, output: Path | None, single: bool) -> dict[str, Path]:
    """The file each figure goes to. One figure asked for by name (`single`) with -o: that file.
    Otherwise `<stem>_<kind><suffix>` beside -o (its suffix, .png by default: `-o fig.png` writes
    fig_layout.png, fig_modes.png; `-o figs/run` writes figs/run_layout.png) or beside RESULT."""
    if single and output is not None:
        return {kinds[0]: Path(output)}
    base = Path(output) if output is not None else Path(result)
    suffix = base.suffix if base.suffix.lower() in (".png", ".svg", ".pdf") else ".png"
    stem = base.name[: -len(base.suffix)] if base.suffix.lower() in (".png", ".svg", ".pdf", ".h5") else base.name
    return {k: base.with_name(f"{stem}_{k}{suffix}") for k in kinds}


def parse_modes(text: str | None) -> tuple[int, ...] | None:
    """"1-8" / "1,3,5" / "2-4,7" -> mode numbers (1-based); None for all (up to 8)."""
    if not text:
        return None
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-", 1)
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return tuple(out)


def swept_parameter(res: Results) -> tuple[str, np.ndarray, str]:
    """(dotted key as given, its values (case,), its units) of the first swept parameter."""
    g = res.groups["sweep"]
    keys = [k for k in g["variables"] if k.startswith("param_")]
    if not keys:
        raise OutputError(f"{res.path}: /sweep has no swept parameter")
    dataset = keys[0]
    name = dataset[len("param_"):]
    try:  # the dotted key as given (tension.target), from the sweep's own record of its parameters
        name = json.loads(g["attrs"].get("params", "[]"))[0]["key"]
    except (ValueError, KeyError, IndexError, TypeError):
        pass
    units = str(g["units"].get(dataset, ""))
    return name, np.asarray(g["variables"][dataset], dtype=float), "" if units == "unknown" else units


def warnings_of(res: Results) -> list[tuple[str, str]]:
    """(group, warning) of every group's `warnings` attribute (a JSON list or a list), in file order."""
    out = []
    for name, g in res.groups.items():
        w = g["attrs"].get("warnings")
        if w is None:
            continue
        if isinstance(w, str):
            try:
                w = json.loads(w)
            except ValueError:
                w = [w]
        out += [(name, str(x)) for x in np.atleast_1d(w) if str(x)]
    return out


def channel_names(g: dict, dims) -> list[str]:
    """The names of the flattened trailing axes of a variable: the coordinate values joined."""
    axes = [[str(v) for v in g["coords"].get(d, [])] or [d] for d in dims]
    return [" ".join(c) for c in itertools.product(*axes)] if axes else [""]


def meaningful_margin(value: float) -> bool:
    """A slip margin worth showing: finite and below SLIP_CAP (a torque-free pulley's is infinite)."""
    return bool(np.isfinite(value) and abs(value) < SLIP_CAP)
