"""The one component assembly (dense and sparse on one `Pattern`), the former component paths against it,
and the immutability of what a build makes (no hidden caches in frozen objects)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import csr_matrix

from beltdyn.analysis.modal import solve_modes
from beltdyn.analysis.static import solve_static
from beltdyn.config import config_from_dict, load_config
from beltdyn.model.assembly import component_sums, make_pattern
from beltdyn.model.geometry import layout_from_config
from beltdyn.model.system import DeferredSystem, build_system, drive_facts

from test_system import TWO_ARMS

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


def _two_arms_under_gravity():
    return config_from_dict({**TWO_ARMS, "model": {"gravity": [0.0, -9.81]}})


def _drives():
    """The two-arm drive under gravity (arms with springs relaxed off the layout, a bearing, a slide, spring
    and ANCF spans) and the FEAD example under gravity (tensioner arm, 10 el/span)."""
    return [("two arms", _two_arms_under_gravity()), ("FEAD", load_config(FEAD, ["model.gravity=[0.0, -9.81]"]))]


def _dense(a) -> np.ndarray:
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a)


def _close(a, b) -> None:
    """a == b to 1e-13 of the largest entry of b (the two paths sum an entry's parts in different orders)."""
    a, b = _dense(a), _dense(b)
    scale = np.abs(b).max()
    assert scale > 0
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * scale)


@pytest.mark.parametrize("name, cfg", _drives())
def test_dense_and_sparse_assembly_agree_on_random_states(name, cfg):
    # Reference: the same drive assembled the other way (dense bincount over (n+1)^2 slots vs CSR data slots of
    # the one pattern): mass, components' stiffness and damping, weight, offsets, and at random states the
    # internal force, its tangent and the belt damping matrix.
    lay = layout_from_config(cfg)
    n = drive_facts(cfg, lay).dofs.n
    kw = dict(prestrain_stretch=np.linspace(1.001, 1.002, lay.n), spring_free=np.linspace(-1e-3, 1e-3, n))
    dense, sparse = build_system(cfg, lay, dense=True, **kw), build_system(cfg, lay, dense=False, **kw)
    assert dense.dense and not sparse.dense and not dense.pattern.sparse and sparse.pattern.sparse
    _close(dense.mass, sparse.mass)
    _close(dense.linear_matrix(), sparse.linear_matrix())
    _close(dense.linear_damping, sparse.linear_damping)
    _close(dense.gravity_force, sparse.gravity_force)
    if dense.linear_offset is not None:
        _close(dense.linear_offset, sparse.linear_offset)
    rng = np.random.default_rng(24)
    Ce = rng.standard_normal((dense.belt.elements.n_elem, 8, 8)) * 1e-3
    for _ in range(3):
        q = rng.standard_normal(dense.n_dof) * 1e-4
        _close(dense.internal_force(q), sparse.internal_force(q))
        f_d, K_d = dense.force_and_tangent(q)
        f_s, K_s = sparse.force_and_tangent(q)
        _close(f_d, f_s)
        _close(K_d, K_s)
        _close(dense.mass_matrix(q), sparse.mass_matrix(q))
        if len(Ce):
            _close(dense.belt_damping_matrix(q, Ce), sparse.belt_damping_matrix(q, Ce))


def _former_dense(components, n, M, fg, g):
    """The former dense path (system._add_components before issue 24), verbatim: one-DOF components as
    scalars, the others by fancy indexing, added in place."""
    K = C = offset = None
    for c in components:
        d = c.dofs
        if len(d) == 1:
            d = int(d[0])
            at, of = (d, d), (0, 0)
        else:
            at, of = (d[:, None], d), ()
        if c.stiffness is not None:
            if K is None:
                K = np.zeros((n, n))
            K[at] += c.stiffness[of]
            if c.free is not None:
                if offset is None:
                    offset = np.zeros(n)
                offset[d] += c.stiffness[of] * c.free[0] if of else c.stiffness @ np.asarray(c.free, dtype=float)
        if c.damping is not None:
            if C is None:
                C = np.zeros((n, n))
            C[at] += c.damping[of]
        if c.mass is not None:
            M[at] += c.mass[of]
        if c.weight is not None:
            fg[d] += (c.weight @ g)[of[1:]]
    return K, C, offset


def _former_sparse(components, pattern, attr):
    """The former sparse path (assembly._summed_sparse before issue 24), verbatim: np.add.at on the slots."""
    mats = [(c.dofs, mat) for c in components if (mat := getattr(c, attr)) is not None]
    if not mats:
        return None
    r = np.concatenate([np.repeat(d, len(d)) for d, _ in mats])
    c = np.concatenate([np.tile(d, len(d)) for d, _ in mats])
    v = np.concatenate([np.asarray(mat, dtype=float).ravel() for _, mat in mats])
    data = np.zeros(pattern.nnz)
    np.add.at(data, pattern.slots_of(r, c), v)
    return data


@pytest.mark.parametrize("name, cfg", _drives())
def test_the_former_component_paths_are_the_one_implementation(name, cfg):
    # Reference: the two former implementations (kept verbatim above) on the drive's components and on random
    # extra components of one, two and three DOFs with free values and weights: to 1e-15 of the largest entry.
    system = build_system(cfg, dense=True)
    n, g = system.n_p, system.gravity if np.any(system.gravity) else np.array([0.3, -9.81])
    rng = np.random.default_rng(7)
    from beltdyn.model.components import LinearComponent

    extra = []
    for k in (1, 2, 3, 1):
        d = rng.choice(n, size=k, replace=False).astype(np.int64)
        A = rng.standard_normal((k, k))
        extra.append(LinearComponent(name=f"random {k}", dofs=d, stiffness=A @ A.T, damping=A.T @ A, mass=A @ A.T + np.eye(k),
                                     weight=rng.standard_normal((k, 2)), free=rng.standard_normal(k)))
    components = system.components + tuple(extra)
    dense_pattern = make_pattern(system.belt.idx, n, sparse=False)
    sums = component_sums(components, dense_pattern, g)
    M, fg = np.zeros((n, n)), np.zeros(n)
    K, C, offset = _former_dense(components, n, M, fg, g)
    for new, old in ((sums.stiffness, K), (sums.damping, C), (sums.mass, M), (sums.offset, offset), (sums.weight, fg)):
        np.testing.assert_allclose(new, old, rtol=0, atol=1e-15 * np.abs(old).max())
    rows, cols = np.nonzero(K + C + M)
    sparse_pattern = make_pattern(system.belt.idx, n, sparse=True, extra=(rows, cols))
    sparse = component_sums(components, sparse_pattern, g)
    for attr, new in (("stiffness", sparse.stiffness), ("damping", sparse.damping.data), ("mass", sparse.mass)):
        old = _former_sparse(components, sparse_pattern, attr)
        np.testing.assert_allclose(new, old, rtol=0, atol=1e-15 * np.abs(old).max())
    np.testing.assert_allclose(csr_matrix((sparse.mass, sparse_pattern.indices, sparse_pattern.indptr),
                                          shape=(n, n)).toarray(), M, rtol=0, atol=1e-15 * np.abs(M).max())


def _frozen_objects(system, facts):
    """Every frozen dataclass of a build: the system, its belt, spring spans, DOF map, pattern, tension setting,
    running terms, components and the configuration's facts. (`ArmJoints`, model/arms.py, is the laws
    engineer's: its cached properties are left to that change.)"""
    objs = [facts, facts.tension, facts.dofs, system, system.belt, system.springs, system.dofs, system.pattern,
            system.tension, system.running_terms, *system.components]
    return [o for o in objs if o is not None]


@pytest.mark.parametrize("speed", [0.0, 12.0])
def test_a_built_system_is_really_immutable(speed):
    # Reference: the dataclass contract. After a build and its use (static, modal, outputs, the compiled kernel's
    # tables, the running belt's terms), every frozen dataclass of it holds exactly its declared fields (no cache
    # written into it) and refuses an assignment to any field.
    fead = load_config(FEAD, [f"running.belt_speed={speed}"])
    springs = load_config(FEAD, [f'spans.{n}.model="spring"' for n in fead.span_names] + [f"running.belt_speed={speed}"])
    for cfg in (_two_arms_under_gravity(), fead, springs):
        lay = layout_from_config(cfg)
        facts = drive_facts(cfg, lay)
        for dense in (True, False):
            system = build_system(cfg, lay, facts=facts, dense=dense)
            st = solve_static(system, cfg.static)
            solve_modes(system, st.q, n_modes=4)
            system.joint_reactions(st.q)
            system.transport_matrices()
            compiled = system.with_belt(compiled=True, damping_axial=1e-5)
            p = compiled.expand(st.q)[None]
            compiled.span_end_forces(p, np.zeros_like(p))
            for s in (system, compiled):
                for obj in _frozen_objects(s, facts):
                    names = {f.name for f in dataclasses.fields(obj)}
                    assert set(vars(obj)) == names, (type(obj).__name__, set(vars(obj)) ^ names)
                    for name in names:
                        with pytest.raises(dataclasses.FrozenInstanceError):
                            setattr(obj, name, getattr(obj, name))


def test_the_deferred_system_gives_the_built_systems_facts():
    # Reference: the system built on the same layout. The deferred system's facts (before any build) are the
    # built system's: the components' stiffness, each arm's spring, DOF map and tension setting; only
    # `full` (or the weight, which holds the belt's) builds.
    cfg = _two_arms_under_gravity()
    lay = layout_from_config(cfg)
    built = []
    deferred = DeferredSystem(cfg, lay, lambda la: built.append(build_system(cfg, la)) or built[-1])
    np.testing.assert_array_equal(_dense(deferred.linear_matrix()), _dense(build_system(cfg, lay).linear_matrix()))
    system = build_system(cfg, lay)
    for dof in system.arms.dof:
        a, b = deferred.arm_spring(int(dof)), system.arm_spring(int(dof))
        assert a is not None and a.name == b.name
        np.testing.assert_array_equal(a.stiffness, b.stiffness)
    assert deferred.tension == system.tension and deferred.dofs.labels == system.dofs.labels
    np.testing.assert_array_equal(deferred.belt.reference_length, system.belt.reference_length)
    assert not deferred.built and not built
    np.testing.assert_array_equal(deferred.gravity_force, system.gravity_force)
    assert deferred.built and deferred.full() is built[0] and len(built) == 1


def _arrays(obj) -> dict:
    """The numpy arrays a frozen dataclass holds, by field name."""
    return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj) if isinstance(getattr(obj, f.name), np.ndarray)}


def test_a_study_store_gives_what_an_analysis_would_make_and_makes_each_item_once():
    # Reference: the analyses without a store (each makes its own fit, DOF map and pattern). Three analyses of
    # the FEAD on a sparse mesh (30 el/span) sharing one `Reuse`: two belt stiffnesses of one drive and a finer mesh.
    # The store makes one fit (one geometry), two DOF maps and two patterns (two meshes); every static and modal
    # result equals the analysis without a store to the bit; what it holds is read-only.
    from beltdyn.model.reuse import Reuse
    from beltdyn.pipeline import analyse

    cfgs = [load_config(FEAD, [f"mesh.elements_per_span={n}", f"belt.EA={ea}"])
            for n, ea in ((30, 1.2e5), (30, 1.5e5), (40, 1.2e5))]
    reuse = Reuse()
    shared = [analyse(c, modal=True, reuse=reuse) for c in cfgs]
    alone = [analyse(c, modal=True) for c in cfgs]
    assert reuse.made == {"fit": 1, "dofs": 2, "pattern": 2}
    assert shared[0].system.pattern is shared[1].system.pattern is not shared[2].system.pattern
    assert shared[0].system.dofs is shared[1].system.dofs and shared[0].fit_layout is shared[2].fit_layout
    for got, want in zip(shared, alone):
        assert got.system.pattern.sparse and want.system.pattern.sparse
        for name, a in _arrays(want.system.pattern).items():
            np.testing.assert_array_equal(getattr(got.system.pattern, name), a, err_msg=name)
        for f in dataclasses.fields(want.system.dofs):
            a, b = getattr(got.system.dofs, f.name), getattr(want.system.dofs, f.name)
            np.testing.assert_equal(a, b, err_msg=f.name)
        for name in ("q", "span_tension", "pulley_center"):
            np.testing.assert_array_equal(getattr(got.static, name), getattr(want.static, name), err_msg=name)
        np.testing.assert_array_equal(got.modal.frequency, want.modal.frequency)
    for obj in (shared[0].system.pattern, shared[0].system.dofs, shared[0].fit_layout):
        for name, a in _arrays(obj).items():
            assert not a.flags.writeable, f"{type(obj).__name__}.{name}"
