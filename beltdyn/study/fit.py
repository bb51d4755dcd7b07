"""Identification of a drive's parameters from measured natural frequencies (`beltdyn fit`).

Nomenclature: m measured rows (`study.measured.MeasuredData`), n fitted parameters p (n,) (dotted
configuration keys), x (n,) their scaled values: x = ln(p / p0) for a positive parameter, x =
(p - p0) / s (s = |p0|, or 1 for p0 = 0) otherwise; f (m,) the computed frequencies paired with the
rows, f^ (m,) the measured ones, w (m,) the rows' weights.

Residuals r = sqrt(w) (f - f^) / f^ (relative), minimized by bounded nonlinear least squares
(scipy.optimize.least_squares, trust-region reflective) in x; the Jacobian dr/dx = sqrt(w) / f^ x
df/dp x dp/dx comes from the frequency sensitivities (`analysis.sensitivity`: phi^T (dK - lambda dM)
phi of the mass-normalized shapes, dK and dM by central differences of the matrices of the drive
rebuilt at the same static state) where the parameter does not move the equilibrium, and from central
differences of whole analyses (static + modal) where it does (EA with a tension target, the tension,
a mass under gravity), or where the parameter changes the belt path or the belt runs.

Load cases: the rows of one case (the same values of the key columns) are compared with one analysis
of the configuration with those overrides.

Pairing (made once, at the initial parameters, and kept by label during the fit): a row with a kind
(and order, span) pairs with the computed mode of that classification nearest to it; a row without
pairs with the nearest computed mode, one to one over the case's unclassified rows (optimal
assignment); two candidates within a row's scatter make its pairing ambiguous (a warning). The
near-degenerate pairs (the upper and lower spans' transverse modes of equal order, within
DEGENERATE_RTOL) are one candidate unless the row names the span: its frequency and its sensitivity
are the pair's means (smooth where each member's are not).

Statistics at the solution: s^2 = r^T r / (m - n) (the residual variance), cov(x) = s^2 (J^T J)^-1,
sd(p) = sqrt(cov(x)_jj) dp/dx (linearized), the correlation matrix of x (that of p to first order).
Identifiability: a parameter whose Jacobian column is (nearly) zero, or that belongs to a (nearly)
dependent set of columns (the column-normalized Jacobian's smallest singular value below
SINGULAR_RTOL of its largest), is named and held at its initial value, never fitted silently.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from beltdyn.analysis.modal import ModalResult, ordinal
from beltdyn.analysis.sensitivity import (
    equilibrium_moves,
    frequency_derivatives,
    matrix_derivatives,
    same_matrices,
)
from beltdyn.config import DriveConfig, config_to_dict, with_overrides
from beltdyn.errors import ConfigError, SolverError
from beltdyn.model.reuse import Reuse
from beltdyn.model.system import System, build_system, drive_facts
from beltdyn.pipeline import Analysis, analyse
from beltdyn.study.measured import MeasuredData, check_cases

DEGENERATE_RTOL = 1e-3  # two modes of one kind and order closer than this (relative) are one candidate
SINGULAR_RTOL = 1e-6  # a column-normalized Jacobian this close to rank deficient leaves parameters undetermined
ZERO_SENSITIVITY = 1e-9  # |dr/dx| below this: the parameter changes no measured frequency
POORLY_DETERMINED = 0.5  # a relative standard deviation above this is a warning
STEP = 1e-4  # relative step of the central differences (matrices and whole analyses)
# keys that enter the system's matrices only (not the belt path): their derivative may be taken at a fixed state
STATE_KEYS = ("belt.EI", "belt.EA", "belt.mass_per_length")
PULLEY_STATE_KEYS = ("mass", "inertia", "bearing_stiffness", "arm_inertia", "arm_stiffness")


@dataclass(frozen=True, kw_only=True)
class FitParameter:
    """A parameter to identify: a dotted configuration key, its initial value, its bounds (physical
    units; +-inf: none) and whether it is fitted in log (a positive parameter with lower >= 0)."""

    key: str
    initial: float
    lower: float = -math.inf
    upper: float = math.inf
    log: bool = True

    def value(self, x: float) -> float:
        """p of the scaled value x."""
        return self.initial * math.exp(x) if self.log else self.initial + x * self.scale

    def slope(self, x: float) -> float:
        """dp/dx at x."""
        return self.value(x) if self.log else self.scale

    @property
    def scale(self) -> float:
        return abs(self.initial) or 1.0

    def scaled_bounds(self) -> tuple[float, float]:
        """The bounds on x."""
        if self.log:
            lo = math.log(self.lower / self.initial) if self.lower > 0.0 else -math.inf
            hi = math.log(self.upper / self.initial) if math.isfinite(self.upper) else math.inf
            return lo, hi
        return (self.lower - self.initial) / self.scale, (self.upper - self.initial) / self.scale


def parameter_value(cfg: DriveConfig, key: str) -> float:
    """The number a dotted key ("belt.EI", "pulleys[0].inertia", "pulleys.A.inertia",
    "pulleys.0.bearing_stiffness") holds in cfg (a [kx, ky] stiffness given as one number: kx).
    ConfigError (exit 2, key --param) if there is none."""
    import re

    node = config_to_dict(cfg)
    for piece in re.sub(r"\[(\d+)\]", r".\1", key).split("."):
        if isinstance(node, list):
            named = [x for x in node if isinstance(x, dict) and x.get("name") == piece]
            if named:
                node = named[0]
            elif piece.isdigit() and int(piece) < len(node):
                node = node[int(piece)]
            else:
                node = None
        elif isinstance(node, dict):
            node = node.get(piece)
        else:
            node = None
        if node is None:
            break
    if isinstance(node, list) and node and all(isinstance(v, (int, float)) for v in node) and len(set(node)) == 1:
        node = node[0]  # an isotropic bearing stiffness
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        raise ConfigError(f"{key!r} is not a number of the configuration (got {node!r})", file=cfg.source,
                          key=f"--param {key}")
    return float(node)


def parse_parameter(cfg: DriveConfig, text: str) -> FitParameter:
    """A --param value: KEY or KEY=LOW:HIGH (bounds; either may be empty). Its initial value is the
    configuration's; a positive initial value with a lower bound >= 0 (or none) is fitted in log."""
    key, _, spec = text.partition("=")
    key = key.strip()
    p0 = parameter_value(cfg, key)
    lo, hi = -math.inf, math.inf
    if spec.strip():
        parts = spec.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            lo = float(parts[0]) if parts[0].strip() else -math.inf
            hi = float(parts[1]) if parts[1].strip() else math.inf
        except ValueError:
            raise ConfigError(f"bounds must be LOW:HIGH, got {spec!r}", file=cfg.source,
                              key=f"--param {text}") from None
        if not lo < hi:
            raise ConfigError(f"LOW must be below HIGH, got {spec!r}", file=cfg.source, key=f"--param {text}")
        if not lo <= p0 <= hi:
            raise ConfigError(f"the initial value {p0:g} (the configuration's) is outside {spec}", file=cfg.source,
                              key=f"--param {text}")
    log = p0 > 0.0 and lo >= 0.0 if math.isfinite(lo) else p0 > 0.0
    if log and not math.isfinite(lo):
        lo = 0.0
    return FitParameter(key=key, initial=p0, lower=lo, upper=hi, log=log)


@dataclass(frozen=True, kw_only=True)
class Candidate:
    """A computed mode a row pairs with: kind, order and the span(s) of its members (a near-degenerate
    pair: both spans), found again in any analysis by these."""

    kind: str
    order: int
    spans: tuple[int, ...]

    def members(self, modal: ModalResult) -> np.ndarray:
        """The mode indices of this candidate in a modal result."""
        return np.flatnonzero([k == self.kind and o == self.order and s in self.spans
                               for k, o, s in zip(modal.kind, modal.order.tolist(), modal.span.tolist())])

    def label(self, modal: ModalResult) -> str:
        idx = self.members(modal)
        if len(idx) == 1:
            return modal.label[int(idx[0])]
        spans = "+".join(str(s) for s in self.spans)
        return f"{ordinal(self.order)} {self.kind}, spans {spans} (mean)"


@dataclass(frozen=True, kw_only=True)
class FitResult:
    """What `fit` found. n parameters, m measured rows."""

    keys: tuple[str, ...]  # (n,)
    initial: np.ndarray  # (n,)
    fitted: np.ndarray  # (n,) (the initial value where not identifiable)
    std: np.ndarray  # (n,) standard deviation (NaN where not identifiable or without redundancy, m = n)
    lower: np.ndarray  # (n,) bounds
    upper: np.ndarray  # (n,)
    correlation: np.ndarray  # (n, n) NaN rows/columns for the parameters not fitted
    identifiable: np.ndarray  # (n,) bool
    method: tuple[str, ...]  # (n,) how the sensitivities were taken: "modal" or "analyses"
    measured: np.ndarray  # (m,) Hz
    weight: np.ndarray  # (m,)
    reference: np.ndarray  # (m,) Hz, NaN where the file gives none
    row_line: np.ndarray  # (m,) line of each row in the measured file
    case: np.ndarray  # (m,) load case of each row
    cases: tuple[str, ...]  # the load cases in words
    mode_label: tuple[str, ...]  # (m,) the paired computed mode
    before: np.ndarray  # (m,) Hz, computed at the initial parameters
    after: np.ndarray  # (m,) Hz, at the fitted ones
    rms_before: float  # RMS of the relative errors (f - f^) / f^ (unweighted)
    rms_after: float
    residual_variance: float  # s^2 = r^T r / (m - n) of the weighted relative residuals (NaN for m = n)
    evaluations: int  # analyses of the model (each: all load cases)
    status: str  # the optimizer's message
    warnings: tuple[str, ...]
    measured_file: str


def system_at_state(cfg: DriveConfig, run: Analysis) -> System:
    """The drive of cfg built on the layout and at the reference state of an analysed drive `run`
    (same spans' stretch, same springs' anchors): with cfg = run.config the same system (checked by
    the caller, `same_matrices`); with a changed material or pulley parameter that drive at the
    same state, for derivatives of its matrices there."""
    s = run.system
    free = np.zeros(s.n_p)
    for c in s.components:
        if c.free is not None:
            free[c.dofs] = c.free
    stretch = s.belt.span_stretch if s.belt.span_stretch is not None else s.belt.prestrain_stretch
    facts = drive_facts(cfg, run.fit_layout if run.fit_layout is not None else run.layout)
    return build_system(cfg, run.layout, prestrain_stretch=stretch, spring_free=free, belt_speed=s.belt_speed,
                        facts=facts)


def state_key(key: str) -> bool:
    """Whether a key enters the system's matrices only (not the belt path), so that its derivative
    may be taken at a fixed state (if the equilibrium does not move, `equilibrium_moves`)."""
    import re

    k = re.sub(r"\[(\d+)\]", r".\1", key)
    if k in STATE_KEYS:
        return True
    parts = k.split(".")
    return len(parts) == 3 and parts[0] == "pulleys" and parts[2] in PULLEY_STATE_KEYS


def _assignment(cfg: DriveConfig, key: str, value: float) -> str:
    return f"{key}={float(value)!r}"


def _modes_needed(cfg: DriveConfig, data: MeasuredData, rows: np.ndarray) -> int:
    """Modes to compute for a case: the configuration's, and enough for its rows (every span's
    transverse modes up to the highest order asked for, and the others)."""
    top = int(data.order[rows].max(initial=0))
    return max(cfg.modal.modes, 2 * len(rows) + 4, len(cfg.pulleys) * top + 4)


def _clusters(modal: ModalResult, pool: np.ndarray) -> list[np.ndarray]:
    """The modes `pool` grouped into candidates: equal kind and order, frequencies within
    DEGENERATE_RTOL of each other (consecutive, ascending)."""
    out: list[list[int]] = []
    f = modal.frequency
    for i in sorted(pool.tolist(), key=lambda j: f[j]):
        for c in out:
            j = c[-1]
            if modal.kind[j] == modal.kind[i] and modal.order[j] == modal.order[i] \
                    and abs(f[i] - f[j]) <= DEGENERATE_RTOL * f[j]:
                c.append(i)
                break
        else:
            out.append([i])
    return [np.array(c) for c in out]


def _candidate(modal: ModalResult, members: np.ndarray) -> Candidate:
    i = int(members[0])
    spans = tuple(sorted(int(modal.span[j]) for j in members))
    return Candidate(kind=modal.kind[i], order=int(modal.order[i]), spans=spans)


def pair_rows(data: MeasuredData, rows: np.ndarray, modal: ModalResult) -> tuple[list[Candidate], list[str]]:
    """The candidate of each of a case's rows (module docstring) and the warnings of ambiguous pairings.
    ConfigError naming the file, row and column for a classification no computed mode has."""
    from scipy.optimize import linear_sum_assignment

    f = modal.frequency
    out: list[Candidate | None] = [None] * len(rows)
    used: set[int] = set()
    warnings = []
    n = len(f)
    for a, r in enumerate(rows.tolist()):
        kind, order, span = data.kind[r], int(data.order[r]), int(data.span[r])
        if not kind:
            continue
        line = int(data.line[r])
        pool = np.flatnonzero([k == kind for k in modal.kind])
        column = "kind"
        if len(pool) and order:
            pool, column = pool[modal.order[pool] == order], "order"
        if len(pool) and span:
            pool, column = pool[modal.span[pool] == span], "span"
        if not len(pool):
            what = " ".join(x for x in (ordinal(order) if order else "", kind) if x)
            what += f" of span {span}" if span else ""
            kinds = ", ".join(sorted(set(modal.kind)))
            raise ConfigError(f"no computed mode is a {what} among the lowest {n} modes of the case "
                              f"'{data.case_name(int(data.case[r]))}' (kinds there: {kinds})",
                              file=data.file, key=f"row {line}, column '{column}'")
        near = int(pool[np.argmin(np.abs(f[pool] - data.frequency[r]))])
        members = np.array([near]) if span else next(c for c in _clusters(modal, pool) if near in c)
        out[a] = _candidate(modal, members)
        used.update(members.tolist())
    free_rows = [a for a, r in enumerate(rows.tolist()) if not data.kind[r]]
    if free_rows:
        clusters = _clusters(modal, np.array([i for i in range(n) if i not in used], dtype=np.int64))
        fc = np.array([f[c].mean() for c in clusters])
        fm = data.frequency[rows[free_rows]]
        if len(free_rows) > len(clusters):
            r = int(rows[free_rows[0]])
            raise ConfigError(f"more unclassified rows ({len(free_rows)}) than computed modes left ({len(clusters)}) "
                              f"in the case '{data.case_name(int(data.case[r]))}'", file=data.file,
                              key=f"row {int(data.line[r])}, column 'frequency'")
        cost = np.abs(fc[None, :] - fm[:, None]) / fm[:, None]
        rr, cc = linear_sum_assignment(cost)
        for i, j in zip(rr.tolist(), cc.tolist()):
            a = free_rows[i]
            r = int(rows[a])
            out[a] = _candidate(modal, clusters[j])
            close = np.flatnonzero(np.abs(fc - fm[i]) <= data.scatter[r])
            if len(close) >= 2:
                names = " and ".join(f"{_candidate(modal, clusters[k]).label(modal)} ({fc[k]:.5g} Hz)"
                                     for k in close[:2])
                warnings.append(f"{data.file}: row {int(data.line[r])}: pairing of {fm[i]:.5g} Hz is ambiguous: "
                                f"{names} are within its scatter {data.scatter[r]:.3g} Hz")
    return out, warnings  # type: ignore[return-value]


class Model:
    """The measured rows' computed frequencies as functions of the parameters (one analysis per load
    case), with their derivatives, for a fixed pairing. Holds the configurations of the cases."""

    def __init__(self, cfg: DriveConfig, data: MeasuredData, params: tuple[FitParameter, ...]) -> None:
        taken = set(data.case_keys) & {p.key for p in params}
        if taken:
            raise ConfigError(f"{', '.join(sorted(taken))} is both a fitted parameter and a load-case column of "
                              f"{data.file}", file=cfg.source, key="--param")
        self.cfg = cfg
        self.data = data
        self.params = params
        self.case_cfgs = check_cases(cfg, data)
        self.rows = tuple(np.flatnonzero(data.case == c) for c in range(len(data.cases)))
        self.n_modes = tuple(_modes_needed(c, data, r) for c, r in zip(self.case_cfgs, self.rows))
        self.pairing: list[list[Candidate]] | None = None
        self.labels: list[str] = [""] * data.n_rows
        self.warnings: list[str] = []
        self.analyses = 0
        self.rebuilt: dict[int, bool] = {}  # per case: `system_at_state` reproduces its drive
        self.reuse = Reuse()  # the L0 fits, DOF maps and patterns of the analyses so far (`pipeline.analyse`'s)

    def config(self, c: int, values: np.ndarray) -> DriveConfig:
        """Case c's configuration at parameter values (n,)."""
        return with_overrides(self.case_cfgs[c], [_assignment(self.cfg, p.key, v) for p, v in zip(self.params, values)])

    def _analyse(self, cfg: DriveConfig, c: int) -> Analysis:
        self.analyses += 1
        try:
            return analyse(cfg, modal=True, n_modes=self.n_modes[c], reuse=self.reuse)
        except SolverError as exc:
            raise SolverError(f"{exc} (fit, load case '{self.data.case_name(c)}')", analysis="fit") from None

    def _frequencies(self, c: int, modal: ModalResult) -> np.ndarray:
        out = np.empty(len(self.rows[c]))
        for a, cand in enumerate(self.pairing[c]):
            idx = cand.members(modal)
            if not len(idx):
                r = int(self.rows[c][a])
                raise SolverError(f"the mode paired with row {int(self.data.line[r])} ({self.labels[r]}) is no longer "
                                  f"among the computed modes", analysis="fit", step=f"case '{self.data.case_name(c)}'")
            out[a] = modal.frequency[idx].mean()
        return out

    def frequencies(self, values: np.ndarray) -> tuple[np.ndarray, tuple[Analysis, ...]]:
        """Computed frequencies (m,) of the rows at parameter values (n,), and each case's analysis.
        The first call pairs the rows with the computed modes (kept for the later calls)."""
        freq = np.empty(self.data.n_rows)
        runs = []
        for c, rows in enumerate(self.rows):
            run = self._analyse(self.config(c, values), c)
            if self.pairing is None or len(self.pairing) <= c:
                pairs, warns = pair_rows(self.data, rows, run.modal)
                self.pairing = (self.pairing or []) + [pairs]
                self.warnings += warns
                for r, cand in zip(rows.tolist(), pairs):
                    self.labels[r] = cand.label(run.modal)
            freq[rows] = self._frequencies(c, run.modal)
            runs.append(run)
        return freq, tuple(runs)

    def derivatives(self, values: np.ndarray, runs: tuple[Analysis, ...], active: np.ndarray | None = None
                    ) -> tuple[np.ndarray, tuple[str, ...]]:
        """df/dp (m, n) of the rows at parameter values (n,) (`runs`: the cases' analyses there, from
        `frequencies`) for the `active` parameters (bool (n,), default all; zero columns for the
        others), and how each was taken ("modal": from the eigenvectors at a fixed state;
        "analyses": central differences of whole analyses)."""
        n = len(self.params)
        active = np.ones(n, dtype=bool) if active is None else active
        deriv = np.zeros((self.data.n_rows, n))
        method = ["modal"] * n
        for c, (rows, run) in enumerate(zip(self.rows, runs)):
            for j, p in enumerate(self.params):
                if not active[j]:
                    continue
                h = STEP * (abs(values[j]) or 1.0)
                lo, hi = values.copy(), values.copy()
                lo[j] -= h
                hi[j] += h
                col = None
                if state_key(p.key) and not run.system.belt_speed and self._rebuilds(c, run):
                    col = self._state_derivative(c, run, lo, hi, h)
                if col is None:
                    method[j] = "analyses"
                    f_lo = self._frequencies(c, self._analyse(self.config(c, lo), c).modal)
                    f_hi = self._frequencies(c, self._analyse(self.config(c, hi), c).modal)
                    col = (f_hi - f_lo) / (2.0 * h)
                deriv[rows, j] = col
        return deriv, tuple(method)

    def _rebuilds(self, c: int, run: Analysis) -> bool:
        """Whether `system_at_state` rebuilds case c's drive exactly (checked once per case: the
        derivatives at a fixed state need it)."""
        if c not in self.rebuilt:
            self.rebuilt[c] = same_matrices(system_at_state(run.config, run), run.system, run.static.q)
        return self.rebuilt[c]

    def _state_derivative(self, c: int, run: Analysis, lo: np.ndarray, hi: np.ndarray, h: float
                          ) -> np.ndarray | None:
        """The rows' df/dp of case c from the eigenvectors, or None if the equilibrium moves with p."""
        base = run.system
        s_lo = system_at_state(self.config(c, lo), run)
        s_hi = system_at_state(self.config(c, hi), run)
        q = run.static.q
        if s_lo.n_dof != base.n_dof or s_hi.n_dof != base.n_dof or equilibrium_moves(base, s_lo, s_hi, q):
            return None
        dK, dM = matrix_derivatives(s_lo, s_hi, q, h)
        modal = run.modal
        df = frequency_derivatives(modal.shapes, modal.frequency, dK, dM)
        return np.array([df[cand.members(modal)].mean() for cand in self.pairing[c]])


def _identifiable(J: np.ndarray, keys: tuple[str, ...]) -> tuple[np.ndarray, list[str]]:
    """Which parameters the Jacobian J (m, n) of the scaled residuals determines, and why the others
    are not: a (nearly) zero column, then (nearly) dependent columns, removed one at a time (the one
    with the largest share of the smallest singular vector)."""
    n = J.shape[1]
    ok = np.ones(n, dtype=bool)
    notes = []
    norms = np.linalg.norm(J, axis=0)
    top = float(norms.max(initial=0.0))
    for j in range(n):
        if norms[j] <= ZERO_SENSITIVITY or norms[j] <= ZERO_SENSITIVITY * top:
            ok[j] = False
            notes.append(f"{keys[j]} is not identifiable: no measured frequency depends on it "
                         f"(|d r / d ln p| = {norms[j]:.2e}); held at its initial value")
    while ok.sum() > 1:
        idx = np.flatnonzero(ok)
        A = J[:, idx] / norms[idx]
        _, s, vt = np.linalg.svd(A)  # vt (k, k): its last row spans the smallest (or a null) direction
        smallest = float(s[-1]) if A.shape[0] >= A.shape[1] else 0.0  # fewer rows than columns: rank deficient
        if smallest > SINGULAR_RTOL * s[0]:
            break
        v = np.abs(vt[-1])
        names = [keys[int(idx[k])] for k in np.flatnonzero(v > 0.3)]
        drop = int(idx[int(np.argmax(v))])
        ok[drop] = False
        notes.append(f"{keys[drop]} is not identifiable: the measured frequencies cannot separate "
                     f"{', '.join(names)} (smallest singular value {smallest:.2e} of {s[0]:.2e}); held at its "
                     "initial value")
    return ok, notes


def fit(cfg: DriveConfig, data: MeasuredData, params: tuple[FitParameter, ...] | list[FitParameter], *,
        max_evaluations: int = 60, progress: Callable[[str], None] | None = None) -> FitResult:
    """Identify `params` from the measured rows `data` (module docstring)."""
    from scipy.optimize import least_squares

    params = tuple(params)
    if not params:
        raise ConfigError("give at least one --param KEY to fit", file=cfg.source, key="--param")
    keys = tuple(p.key for p in params)
    if len(set(keys)) != len(keys):
        raise ConfigError("a parameter is given twice", file=cfg.source, key="--param")
    model = Model(cfg, data, params)
    n, m = len(params), data.n_rows
    fm = data.frequency
    sw = np.sqrt(data.weight)
    p0 = np.array([p.initial for p in params])
    before, first_runs = model.frequencies(p0)
    first_derivative, method = model.derivatives(p0, first_runs)
    slope0 = np.array([p.slope(0.0) for p in params])
    J0 = (sw / fm)[:, None] * first_derivative * slope0[None, :]
    ok, notes = _identifiable(J0, keys)
    warnings = list(model.warnings) + notes
    if not ok.any():
        raise ConfigError("no parameter can be identified from these measurements: " + "; ".join(notes),
                          file=data.file, key="--param")
    free = tuple(p for p, k in zip(params, ok) if k)
    idx = np.flatnonzero(ok)
    if m < len(free):
        raise ConfigError(f"{m} measured rows cannot determine {len(free)} parameters", file=data.file, key="--param")
    point: dict = {"x": np.zeros(len(free)), "freq": before, "runs": first_runs, "deriv": first_derivative}

    def values(x: np.ndarray) -> np.ndarray:
        v = p0.copy()
        v[idx] = [p.value(float(xi)) for p, xi in zip(free, x)]
        return v

    def at(x: np.ndarray, *, derivatives: bool) -> dict:
        """The last point's frequencies (and derivatives, computed when first asked for): the optimizer
        asks for the residuals, then, at an accepted step only, for the Jacobian at the same point."""
        if not np.array_equal(x, point["x"]):
            freq, runs = model.frequencies(values(x))
            point.update(x=np.array(x, dtype=float), freq=freq, runs=runs, deriv=None)
            if progress is not None:
                progress(f"analyses {model.analyses}: "
                         + ", ".join(f"{p.key} = {v:.6g}" for p, v in zip(free, values(x)[idx])))
        if derivatives and point["deriv"] is None:
            point["deriv"] = model.derivatives(values(x), point["runs"], ok)[0]
        return point

    def residuals(x: np.ndarray) -> np.ndarray:
        return sw * (at(x, derivatives=False)["freq"] - fm) / fm

    def jacobian(x: np.ndarray) -> np.ndarray:
        slope = np.array([p.slope(float(xi)) for p, xi in zip(free, x)])
        return (sw / fm)[:, None] * at(x, derivatives=True)["deriv"][:, idx] * slope[None, :]

    bounds = np.array([p.scaled_bounds() for p in free]).T
    sol = least_squares(residuals, np.zeros(len(free)), jac=jacobian, bounds=(bounds[0], bounds[1]), method="trf",
                        xtol=1e-8, ftol=1e-10, gtol=1e-10, max_nfev=max_evaluations)
    after = at(sol.x, derivatives=False)["freq"]
    J = jacobian(sol.x)
    r = residuals(sol.x)
    dof = m - len(free)
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    std = np.full(n, math.nan)
    corr = np.full((n, n), math.nan)
    try:
        cov = s2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((len(free), len(free)), math.nan)
        warnings.append("the Jacobian at the solution is singular: no standard deviations")
    sd_x = np.sqrt(np.abs(np.diag(cov)))
    slope = np.array([p.slope(float(xi)) for p, xi in zip(free, sol.x)])
    std[idx] = sd_x * slope
    with np.errstate(invalid="ignore", divide="ignore"):
        corr[np.ix_(idx, idx)] = cov / np.outer(sd_x, sd_x)
    if dof <= 0:
        warnings.append(f"{m} rows for {len(free)} parameters: no redundancy, no standard deviations")
    if not sol.success:
        warnings.append(f"the least squares did not converge: {sol.message}")
    for j, (p, xi) in enumerate(zip(free, sol.x)):
        lo, hi = p.scaled_bounds()
        if xi <= lo + 1e-9 or xi >= hi - 1e-9:
            warnings.append(f"{p.key} stopped at a bound ({p.value(float(xi)):.6g}): the standard deviation "
                            "assumes an interior minimum")
    fitted = p0.copy()
    fitted[idx] = [p.value(float(xi)) for p, xi in zip(free, sol.x)]
    for j in idx.tolist():
        if std[j] > POORLY_DETERMINED * abs(fitted[j]):
            warnings.append(f"{keys[j]} is poorly determined by these measurements: {fitted[j]:.6g} +- {std[j]:.3g} "
                            f"({std[j] / abs(fitted[j]):.0%})")

    def rel(f: np.ndarray) -> float:  # the RMS relative error
        return float(np.sqrt(np.mean(((f - fm) / fm) ** 2)))

    return FitResult(
        keys=keys, initial=p0, fitted=fitted, std=std, lower=np.array([p.lower for p in params]),
        upper=np.array([p.upper for p in params]), correlation=corr, identifiable=ok, method=method,
        measured=fm.copy(), weight=data.weight.copy(), reference=data.reference.copy(), row_line=data.line.copy(),
        case=data.case.copy(), cases=tuple(data.case_name(c) for c in range(len(data.cases))),
        mode_label=tuple(model.labels), before=before, after=after, rms_before=rel(before), rms_after=rel(after),
        residual_variance=s2, evaluations=model.analyses, status=str(sol.message), warnings=tuple(warnings),
        measured_file=data.file)


def fitted_config(cfg: DriveConfig, result: FitResult) -> DriveConfig:
    """cfg with the identified parameters at their fitted values (the others as given)."""
    return with_overrides(cfg, [_assignment(cfg, k, v) for k, v, ok in
                                zip(result.keys, result.fitted, result.identifiable) if ok])


__all__ = [
    "DEGENERATE_RTOL",
    "SINGULAR_RTOL",
    "STEP",
    "Candidate",
    "FitParameter",
    "FitResult",
    "Model",
    "fit",
    "fitted_config",
    "pair_rows",
    "parameter_value",
    "parse_parameter",
    "state_key",
    "system_at_state",
]
