"""What the analyses of one study share: a store its owner keeps and passes on, never a module-level memo.

A study analyses many configurations of few drives: a sweep's chunk of cases, the fit to measurements,
the mesh refinement, the belt speeds of a forced response. Its owner creates one `Reuse` and hands it to
each analysis (`pipeline.analyse(reuse=)`), which takes from it what an earlier analysis made for the
same inputs, or makes it and adds it:

- the L0 fit, keyed by `geometry.fit_inputs` (the pulleys and the belt's length);
- the DOF map, keyed by `dofs.dof_inputs` (the pulleys and the elements of each span);
- the assembly pattern, keyed by its inputs' content (`assembly.pattern_key`: the element blocks'
  coordinates, the model's size, dense or sparse, the components' and spring spans' entries).

Each is a pure function of its key and immutable (read-only arrays), so what an analysis takes from the
store is what it would have made itself, to the bit. The store lives as long as its owner keeps it, and
grows by one item per distinct key: a sweep keeps one per chunk of cases.
"""

from __future__ import annotations

import numpy as np

from beltdyn.config import DriveConfig
from beltdyn.model.assembly import Pattern, make_pattern, pattern_key
from beltdyn.model.dofs import DofMap, dof_inputs, number_dofs
from beltdyn.model.geometry import Layout, fit_inputs, layout_from_config


class Reuse:
    """The L0 fits, DOF maps and assembly patterns of a study's analyses, by their inputs.

    `made` counts what the store made (its misses) per kind, for the study to report and the tests to
    check."""

    def __init__(self) -> None:
        self._fits: dict[tuple, Layout] = {}
        self._dofs: dict[tuple, DofMap] = {}
        self._patterns: dict[tuple, Pattern] = {}
        self.made = {"fit": 0, "dofs": 0, "pattern": 0}

    def fit(self, cfg: DriveConfig) -> Layout:
        """The L0 fit of cfg (`geometry.layout_from_config`)."""
        key = fit_inputs(cfg)
        if key not in self._fits:
            self._fits[key] = layout_from_config(cfg)
            self.made["fit"] += 1
        return self._fits[key]

    def dof_map(self, cfg: DriveConfig, counts: tuple[int, ...]) -> DofMap:
        """The DOF map of cfg with counts elements per span (`dofs.number_dofs`)."""
        key = dof_inputs(cfg, counts)
        if key not in self._dofs:
            self._dofs[key] = number_dofs(cfg, counts)
            self.made["dofs"] += 1
        return self._dofs[key]

    def pattern(self, idx: np.ndarray, n: int, *, sparse: bool,
                extra: tuple[np.ndarray, np.ndarray] | None = None) -> Pattern:
        """The assembly pattern of element blocks on idx (n_elem, m) over n coordinates (`assembly.make_pattern`)."""
        key = pattern_key(idx, n, sparse=sparse, extra=extra)
        if key not in self._patterns:
            self._patterns[key] = make_pattern(idx, n, sparse=sparse, extra=extra)
            self.made["pattern"] += 1
        return self._patterns[key]
