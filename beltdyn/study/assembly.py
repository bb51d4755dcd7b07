"""The /sweep results, assembled in case order as the cases arrive (`Assembly`, `assemble`).

The results come back from the workers in memory and are assembled in case order as they arrive: only
the small per-case quantities are kept for every case, mode shapes only while a later case is still to
be tracked from them (`tracking.match_modes`); the journal is read back only for the cases of an
earlier run, one at a time, so an interrupted and resumed sweep gives the same file. Every case has a
parent, its neighbour one step back along the last axis that moved (a spanning tree of the grid).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.errors import OutputError

from beltdyn.study.grid import SweepSpec
from beltdyn.study.journal import Journal
from beltdyn.study.tracking import first_selection, match_modes


@dataclass(frozen=True, kw_only=True)
class SweepResult:
    spec: SweepSpec
    values: list[tuple]  # per case
    failed: np.ndarray  # (n_cases,) int8
    errors: list[str]
    wall_time: np.ndarray  # (n_cases,) s
    frequency: np.ndarray | None  # (n_cases, n_track) Hz, tracked
    kind: np.ndarray | None  # (n_cases, n_track) str
    order: np.ndarray | None
    span: np.ndarray | None
    label: np.ndarray | None  # (n_track,) labels at the first case
    mac: np.ndarray | None  # (n_cases, n_track) MAC with the parent's tracked mode (1 for the root)
    extras: dict[str, np.ndarray]  # per-case static / transient quantities (n_cases, ...)
    growth_rate: np.ndarray | None = None  # (n_cases, n_track) 1/s, tracked (> 0: divergence or flutter)


@dataclass(frozen=True, kw_only=True)
class Column:
    """A column of the console's sweep table (issue 26): its title and one cell per case ("" where the
    case failed or lacks the quantity)."""

    title: str
    cells: tuple[str, ...]  # (n_cases,)


def _cells(values: np.ndarray, fmt: str, failed: np.ndarray) -> tuple[str, ...]:
    return tuple("" if failed[i] or not np.isfinite(v) else format(v, fmt) for i, v in enumerate(values))


def static_columns(result: SweepResult, pulleys: list[str]) -> tuple[Column, ...]:
    """What the console shows of a sweep's static results besides the swept values: the mean tension;
    each tensioner arm's angle and spring torque (its working curve over the sweep); the least slip margin
    over the pulleys and the pulley it belongs to (those whose friction is given). `pulleys`: the
    pulleys' names, in the configuration's order (the columns of the per-pulley extras)."""
    x, failed = result.extras, result.failed.astype(bool)
    columns = []
    if "mean_tension" in x:
        columns.append(Column(title="mean tension (N)", cells=_cells(x["mean_tension"], ".3f", failed)))
    if "arm_angle" in x:
        for j, name in enumerate(pulleys):
            if np.isfinite(x["arm_angle"][:, j]).any():
                columns.append(Column(title=f"{name} arm angle (deg)",
                                      cells=_cells(np.degrees(x["arm_angle"][:, j]), ".3f", failed)))
                if "arm_torque" in x:
                    columns.append(Column(title=f"{name} arm torque (N m)",
                                          cells=_cells(x["arm_torque"][:, j], ".4g", failed)))
    if "slip_margin" in x and (~np.isnan(x["slip_margin"])).any():
        # nan: friction not given; inf: the pulley transmits nothing (its two tensions agree)
        margin = x["slip_margin"]
        given = ~np.isnan(margin)
        known = given.any(axis=1)
        least = np.where(known, np.where(given, margin, np.inf).min(axis=1), np.nan)
        where = np.where(given, margin, np.inf).argmin(axis=1)
        named = known & np.isfinite(least) & ~failed  # no pulley is nearest slip where none transmits
        columns.append(Column(title="least slip margin",
                              cells=tuple("" if failed[i] or np.isnan(v) else format(v, ".3f")
                                          for i, v in enumerate(least))))
        columns.append(Column(title="at pulley", cells=tuple(pulleys[where[i]] if named[i] else ""
                                                               for i in range(len(failed)))))
    return tuple(columns)


_MODAL_KEYS = ("frequency", "growth_rate", "shapes", "mshapes", "kind", "order", "span", "label")
_NOT_EXTRA = ("failed", "error", "wall_time", *_MODAL_KEYS)


class Assembly:
    """The /sweep results, built case by case in index order while the sweep runs.

    `offer` takes each finished case as it arrives (any order); `advance` assembles the cases from the
    next one on as far as they are there, from memory or else from the journal (the cases of an earlier
    run, or those arrived too far ahead of the next, of which only the index is kept: at most BUFFER
    cases wait whole in memory). Only the small per-case quantities are kept for every case; mode
    shapes are kept only while a later case may still be tracked from them: a case is tracked from its
    nearest tracked ancestor in the spanning tree of the grid (SweepSpec.parent, past failed cases), so
    a case's shapes are dropped once every case that can reach it that way is assembled (`_refs`
    counts those still to come). Between cases, at most one case per swept parameter is held (the
    last case, and the first of each line still to be continued), whatever the number of cases."""

    BUFFER = 64

    def __init__(self, spec: SweepSpec) -> None:
        n = spec.n_cases
        self.spec = spec
        self.next = 0
        self.failed = np.zeros(n, dtype=np.int8)
        self.errors = [""] * n
        self.wall = np.zeros(n)
        self.extras: dict[str, np.ndarray] | None = None  # from the first case that did not fail
        self.label: np.ndarray | None = None
        self._waiting: dict[int, dict] = {}
        self.modal = spec.analysis == "modal"
        if self.modal:
            k = spec.n_modes
            self.frequency = np.full((n, k), np.nan)
            self.growth = np.full((n, k), np.nan)
            self._kind = np.zeros((n, k), dtype=np.int16)  # codes into _kind_names (0: "")
            self._kind_names: list[str] = ["", "lost"]
            self.order = np.zeros((n, k), dtype=np.int64)
            self.span = np.zeros((n, k), dtype=np.int64)
            self.mac = np.full((n, k), np.nan)
            self._parent = spec.parents()
            self._children = np.bincount(self._parent[1:], minlength=n).astype(np.int64) if n > 1 \
                else np.zeros(n, dtype=np.int64)
            self._rep = np.full(n, -1, dtype=np.int64)  # nearest tracked ancestor-or-self of an assembled case
            self._refs = np.zeros(n, dtype=np.int64)  # cases still to come that will be tracked from this one
            self._kept: dict[int, dict] = {}  # tracked cases whose shapes may still be needed (and their pick)
            self._last = -1  # the last tracked case (a case without a tracked ancestor is tracked from it)

    @property
    def held(self) -> int:
        """Cases whose mode shapes are in memory (waiting or kept for tracking)."""
        return len(self._waiting) + (len(self._kept) if self.modal else 0)

    def offer(self, index: int, case: dict) -> None:
        if index >= self.next and len(self._waiting) < self.BUFFER:
            self._waiting[index] = case

    def advance(self, journal: "Journal") -> None:
        n = self.spec.n_cases
        while self.next < n:
            i = self.next
            case = self._waiting.pop(i, None)
            if case is None:
                if not journal.has(i):
                    return
                case = journal.read(i)
            self._add(i, case)
            self.next += 1

    def _add(self, i: int, c: dict) -> None:
        failed = int(c["failed"])
        self.failed[i] = failed
        self.errors[i] = str(c["error"])
        self.wall[i] = float(c["wall_time"])
        if not failed:
            if self.extras is None:
                n = self.spec.n_cases
                self.extras = {key: np.full((n, *np.shape(c[key])), np.nan) for key in c if key not in _NOT_EXTRA}
            for key, arr in self.extras.items():
                if key in c:
                    arr[i] = c[key]
        if self.modal:
            self._track(i, c, failed)

    def _track(self, i: int, c: dict, failed: int) -> None:
        """MAC tracking of case i from its nearest tracked ancestor (else the last tracked case)."""
        parent = self._parent[i]
        anc = int(self._rep[parent]) if parent >= 0 else -1
        if failed:
            self._rep[i] = anc
            if anc >= 0:  # this case's children will be tracked from its ancestor
                self._refs[anc] += self._children[i]
        else:
            k = self.spec.n_modes
            p = anc if anc >= 0 else self._last
            if p < 0:
                sel, macs = first_selection(k, len(c["frequency"]))
            else:
                sel, macs = match_modes(self._kept[p], c, k)
            ok = sel >= 0
            self.frequency[i, ok] = c["frequency"][sel[ok]]
            if "growth_rate" in c:
                self.growth[i, ok] = c["growth_rate"][sel[ok]]
            self._kind[i, ok] = [self._kind_code(str(x)) for x in c["kind"][sel[ok]]]
            self._kind[i, ~ok] = 1  # "lost"
            self.order[i, ok] = c["order"][sel[ok]]
            self.span[i, ok] = c["span"][sel[ok]]
            self.mac[i, ok] = np.minimum(macs[ok], 1.0)
            if self.label is None:
                self.label = np.array(c["label"][:k])
            self._rep[i] = i
            self._refs[i] += self._children[i]
            self._kept[i] = {key: c[key] for key in ("shapes", "mshapes", "kind", "order", "span", "frequency")}
            self._kept[i]["sel"] = sel
            last, self._last = self._last, i
            if last >= 0:
                self._release(last)
        if anc >= 0:  # this case no longer needs its ancestor
            self._refs[anc] -= 1
            self._release(anc)
        if not failed:
            self._release(i)

    def _kind_code(self, name: str) -> int:
        try:
            return self._kind_names.index(name)
        except ValueError:
            self._kind_names.append(name)
            return len(self._kind_names) - 1

    @property
    def kind(self) -> np.ndarray:
        """(n_cases, n_track) object array of str: a case's tracked modes' classification ("" for a
        failed case, "lost" for a mode that left the computed window), one shared str per kind (the
        codes are kept per case: 2 bytes a mode instead of a string object)."""
        return np.array(self._kind_names, dtype=object)[self._kind]

    def _release(self, j: int) -> None:
        if self._refs[j] <= 0 and j != self._last:
            self._kept.pop(j, None)

    def result(self) -> "SweepResult":
        spec, n = self.spec, self.spec.n_cases
        if self.next < n:
            raise OutputError(f"the sweep is not complete: case {self.next + 1} of {n} is not journaled")
        modal = self.modal
        label = self.label if self.label is not None else np.array([])
        return SweepResult(spec=spec, values=[spec.case_values(i) for i in range(n)], failed=self.failed,
                           errors=self.errors, wall_time=self.wall,
                           frequency=self.frequency if modal else None, kind=self.kind if modal else None,
                           order=self.order if modal else None, span=self.span if modal else None,
                           label=label if modal else None, mac=self.mac if modal else None,
                           extras=self.extras or {}, growth_rate=self.growth if modal else None)


def assemble(spec: SweepSpec, journal: Journal, assembly: Assembly | None = None) -> SweepResult:
    """The sweep's results: those assembled while it ran (`run_sweep` returns its Assembly) completed
    from the journal, or all of them streamed from the journal, one case at a time."""
    if assembly is None or assembly.spec != spec:
        assembly = Assembly(spec)
    assembly.advance(journal)
    return assembly.result()
