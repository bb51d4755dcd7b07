"""The paper's Tables 1 and 2 and their comparison with computed modes.

Reference values: Table 1 (T = 200 N and 400 N, EI = 0.02 N m^2, 10 elements per span) and Table 2
(EI = 100 N m^2, T = 200 N). Each paper mode is matched to a computed mode of the same kind and
order; of a near-degenerate upper/lower span pair of transverse modes the closer one is taken.
"""

from __future__ import annotations

from dataclasses import dataclass

from beltdyn.analysis.modal import ModalResult, ordinal


@dataclass(frozen=True, kw_only=True)
class PaperMode:
    mode: int
    theory: float  # Hz
    experiment: float | None  # Hz
    kind: str
    order: int


@dataclass(frozen=True, kw_only=True)
class PaperCase:
    name: str
    config: str  # stem of configs/paper/<config>.toml
    modes: tuple[PaperMode, ...]


def _m(mode, theory, experiment, kind, order) -> PaperMode:
    return PaperMode(mode=mode, theory=theory, experiment=experiment, kind=kind, order=order)


CASES = (
    PaperCase(name="T1, 200 N", config="bench_T200", modes=(
        _m(1, 30.5, 30.3, "transverse", 1), _m(2, 61.3, 61.1, "transverse", 2),
        _m(3, 92.4, 92.4, "transverse", 3), _m(4, 100.8, None, "rotational", 1),
        _m(5, 124.2, 125.2, "transverse", 4), _m(6, 156.7, 159.2, "transverse", 5),
        _m(7, 178.5, None, "translational", 1), _m(8, 190.3, 194.9, "transverse", 6))),
    PaperCase(name="T1, 400 N", config="bench_T400", modes=(
        _m(1, 43.2, 43.1, "transverse", 1), _m(2, 86.6, 86.5, "transverse", 2),
        _m(3, 101.0, None, "rotational", 1), _m(4, 130.3, 130.1, "transverse", 3),
        _m(5, 174.4, 175.0, "transverse", 4), _m(6, 178.6, None, "translational", 1),
        _m(7, 219.1, 220.0, "transverse", 5), _m(8, 264.5, 266.8, "transverse", 6))),
    PaperCase(name="T2, EI 100", config="bench_EI100", modes=(
        _m(1, 100.8, None, "rotational", 1), _m(2, 105.4, None, "transverse", 1),
        _m(3, 178.5, None, "translational", 1), _m(4, 408.3, None, "transverse", 2),
        _m(5, 761.7, None, "longitudinal", 1), _m(6, 769.6, None, "longitudinal", 2),
        _m(7, 913.3, None, "transverse", 3), _m(8, 1554.6, None, "longitudinal", 3))),
)


@dataclass(frozen=True, kw_only=True)
class Comparison:
    case: str
    mode: int
    shape: str
    theory: float
    experiment: float | None
    ours: float
    our_label: str
    diff_theory_pct: float
    diff_experiment_pct: float | None


def compare(case: PaperCase, res: ModalResult) -> list[Comparison]:
    """Match each paper mode to a computed mode of the same kind and order (KeyError if none)."""
    rows = []
    for pm in case.modes:
        cands = [k for k in range(len(res.frequency)) if res.kind[k] == pm.kind and res.order[k] == pm.order]
        if not cands:
            raise KeyError(f"{case.name}: no computed {ordinal(pm.order)} {pm.kind} mode")
        k = min(cands, key=lambda i: abs(res.frequency[i] - pm.theory))
        f = float(res.frequency[k])
        rows.append(Comparison(
            case=case.name, mode=pm.mode, shape=f"{ordinal(pm.order)} {pm.kind}", theory=pm.theory,
            experiment=pm.experiment, ours=f, our_label=res.label[k],
            diff_theory_pct=100.0 * (f - pm.theory) / pm.theory,
            diff_experiment_pct=None if pm.experiment is None else 100.0 * (f - pm.experiment) / pm.experiment))
    return rows


def markdown_table(rows: list[Comparison]) -> str:
    lines = [
        "| case | mode | modal shape | paper theoretical (Hz) | paper experimental (Hz) | beltdyn (Hz) "
        "| vs theoretical (%) | vs experimental (%) |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        exp = "-" if r.experiment is None else f"{r.experiment:.1f}"
        dexp = "-" if r.diff_experiment_pct is None else f"{r.diff_experiment_pct:+.2f}"
        lines.append(f"| {r.case} | {r.mode} | {r.shape} | {r.theory:.1f} | {exp} | {r.ours:.3f} "
                     f"| {r.diff_theory_pct:+.3f} | {dexp} |")
    worst = max(abs(r.diff_theory_pct) for r in rows)
    lines.append("")
    lines.append(f"Largest difference to the paper's theoretical values: {worst:.3f} % (acceptance: 0.5 %).")
    return "\n".join(lines) + "\n"
