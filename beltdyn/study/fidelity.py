"""The automatic choice of span models (`--fmax F --rtol R`): the cheapest model of each span whose
modes below F are estimated within R of the converged ANCF drive.

The estimators (continuum frequencies, local mesh errors, the spring spans' first-order error) are
`analysis.ladder`'s; this study runs the drives they choose (`pipeline.analyse`): first every span a
spring, then the chosen drive, raising a spring span whose share of the error exceeds its budget.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from beltdyn.analysis.ladder import (MESHES, SPRING_MARGIN, LadderChoice, SpanChoice, continuum_frequencies,
                                     element_blocks, local_error, span_state, spring_errors, unrepresented_modes)
from beltdyn.config import DriveConfig, SpanSetting
from beltdyn.errors import SolverError
from beltdyn.pipeline import analyse


def with_spans(cfg: DriveConfig, models: dict[int, tuple[str, int]]) -> DriveConfig:
    """cfg with a [spans] entry for every span: models[s] = (model, elements) (elements 0 for a spring)."""
    names = cfg.span_names
    spans = tuple((names[s], SpanSetting(model=m, elements=None if m == "spring" else int(n)))
                  for s, (m, n) in sorted(models.items()))
    return replace(cfg, spans=spans)


def mesh_blocks(cfg: DriveConfig, spans: list[int], *, L_ref, lam, meshes: list[int]) -> dict:
    """{span: {model: (tangent, mass) (n_meshes, 8, 8)}}: the element of every candidate mesh of the given
    spans, for the string (no bending) and the ANCF rung, one element build per rung for all of them."""
    b = cfg.belt
    ref_curv = cfg.model.curvature if cfg.model.curvature != "none" else "linear"
    n_m = len(meshes)
    lengths = (np.asarray(L_ref, dtype=float)[spans][:, None] / np.array(meshes, dtype=float)[None, :]).ravel()
    stretch = np.repeat(np.asarray(lam, dtype=float)[spans], n_m)
    built = {model: element_blocks(lengths, stretch=stretch, EA=b.EA, EI=0.0 if model == "string" else b.EI,
                                   rho=b.mass_per_length, curvature="none" if model == "string" else ref_curv,
                                   n_gauss=cfg.model.gauss_points) for model in ("string", "ancf")}
    return {s: {model: (K[i * n_m:(i + 1) * n_m], M[i * n_m:(i + 1) * n_m]) for model, (K, M) in built.items()}
            for i, s in enumerate(spans)}


def mesh_choice(cfg: DriveConfig, s: int, *, fmax: float, budget: float, L_ref, lam, meshes: list[int],
                 blocks: dict) -> tuple[str, int, float]:
    """(model, elements, estimate) of flexible span s: the fewest elements, a string where it is good
    enough; the finest ANCF mesh tried when none meets the budget. blocks: the span's candidate elements
    {model: (tangent, mass) (len(meshes), 8, 8)} (`mesh_blocks`)."""
    b = cfg.belt
    common = dict(fmax=fmax, length=float(L_ref[s]), stretch=float(lam[s]), EA=b.EA, EI=b.EI,
                  rho=b.mass_per_length, curvature=cfg.model.curvature, n_gauss=cfg.model.gauss_points)
    best = ("ancf", MESHES[0], np.inf)
    for i, n_e in enumerate(meshes):
        for model in ("string", "ancf"):
            err = local_error(model=model, elements=n_e, blocks=(blocks[model][0][i], blocks[model][1][i]), **common)
            if err <= budget:
                return model, n_e, err
            if model == "ancf":
                best = ("ancf", n_e, err)
    return best


def choose_models(cfg: DriveConfig, *, fmax: float, rtol: float, max_elements: int = 64):
    """The cheapest model of each span whose modes below fmax are estimated within rtol of the
    converged ANCF drive (module docstring). Returns (LadderChoice, the chosen drive's
    pipeline.Analysis with static and modal results, its modes covering the band)."""
    n = len(cfg.pulleys)
    spring_all = with_spans(cfg, {s: ("spring", 0) for s in range(n)})
    try:
        base = analyse(spring_all, modal=True, n_modes=max(1, n + 8))
    except SolverError as exc:  # say which model failed: the user asked for none of them
        raise SolverError(f"the choice starts from the drive with every span a spring, which failed ({exc})",
                          analysis="span model choice") from None
    _, L_ref, lam = span_state(base.system, base.static)
    b = cfg.belt
    curvature = cfg.model.curvature if cfg.model.curvature != "none" else "linear"
    first = [continuum_frequencies(length=L_ref[s], stretch=lam[s], EA=b.EA, EI=b.EI, rho=b.mass_per_length,
                                   curvature=curvature, n=1) for s in range(n)]
    candidates = [s for s in range(n) if min(first[s][0][0], first[s][1][0]) > SPRING_MARGIN * fmax]
    md = base.modal
    below = md.frequency <= fmax
    e_all = spring_errors(base.system, base.static.q, md.frequency[below], md.shapes[below])  # (modes, n)

    def springs_within(budget: float) -> list[int]:
        chosen = list(candidates)
        while chosen:
            e = e_all[:, chosen]
            tot = e.sum(axis=1)
            if not len(tot) or tot.max() <= budget:
                break
            i = int(np.argmax(tot))
            chosen.pop(int(np.argmax(e[i])))
        return chosen

    springs = springs_within(rtol)
    if len(springs) < n:
        springs = springs_within(0.5 * rtol)
    solves = 1
    meshes = [m for m in MESHES if m <= max_elements]
    blocks: dict = {}  # span -> its candidate meshes' elements (`mesh_blocks`)
    while True:
        flexible = [s for s in range(n) if s not in springs]
        budget = 0.5 * rtol if springs and flexible else rtol
        models: dict[int, tuple[str, int]] = {s: ("spring", 0) for s in springs}
        est: dict[int, float] = {}
        missing = [s for s in flexible if s not in blocks]
        if missing:  # the candidate meshes' elements of the spans not built yet, in one build per rung
            blocks.update(mesh_blocks(cfg, missing, L_ref=L_ref, lam=lam, meshes=meshes))
        for s in flexible:
            m, n_e, err = mesh_choice(cfg, s, fmax=fmax, budget=budget, L_ref=L_ref, lam=lam, meshes=meshes,
                                       blocks=blocks[s])
            models[s], est[s] = (m, n_e), err
        chosen_cfg = with_spans(cfg, models)
        n_local = sum(int(np.searchsorted(f_t, fmax, side="right")) + int(np.searchsorted(f_a, fmax, side="right"))
                      for f_t, f_a in (continuum_frequencies(length=L_ref[s], stretch=lam[s], EA=b.EA, EI=b.EI,
                                                             rho=b.mass_per_length, curvature=curvature, n=64)
                                       for s in flexible))
        n_modes = max(cfg.modal.modes, int(below.sum()) + n_local + 4)
        run = analyse(chosen_cfg, modal=True, n_modes=n_modes)
        solves += 1
        fm = run.modal
        band = fm.frequency <= fmax
        e_spring = spring_errors(run.system, run.static.q, fm.frequency[band], fm.shapes[band])
        flex_part = max([est[s] for s in flexible], default=0.0)
        spring_tot = e_spring.sum(axis=1) if e_spring.size else np.zeros(int(band.sum()))
        spring_budget = 0.5 * rtol if flexible else rtol
        if springs and spring_tot.size and spring_tot.max() > spring_budget:
            i = int(np.argmax(spring_tot))  # raise the rung of the worst spring span and solve again
            springs.pop(int(np.argmax(e_spring[i])))
            continue
        break
    mode_est = spring_tot + flex_part
    sp_est = e_spring.max(axis=0) if e_spring.size else np.zeros(len(springs))
    order = {s: i for i, s in enumerate(run.system.springs.span.tolist())} if run.system.springs is not None else {}
    names = cfg.span_names
    choices = []
    for s in range(n):
        m, n_e = models[s]
        if m == "spring":
            e = float(sp_est[order[s]]) if order and len(sp_est) else 0.0
            note = f"own first mode {min(first[s][0][0], first[s][1][0]):.4g} Hz"
        else:
            e = est[s]
            note = "" if e <= budget else f"does NOT meet {budget:.3g} at {n_e} elements (the finest tried)"
        choices.append(SpanChoice(span=s, name=names[s], model=m, elements=n_e, dofs=4 * n_e, estimate=e, note=note))
    worst = float(mode_est.max(initial=0.0))
    met = worst <= rtol and all(c.note == "" or c.model == "spring" for c in choices)
    return (LadderChoice(fmax=fmax, rtol=rtol, spans=tuple(choices), config=chosen_cfg, met=met, estimate=worst,
                         mode_estimate=mode_est, solves=solves,
                         unrepresented=unrepresented_modes(run.system, run.static, fmax)), run)


__all__ = ["choose_models", "with_spans", "mesh_blocks", "mesh_choice"]
