"""Mode tracking across a sweep: which computed mode of a case continues each tracked mode of its parent.

The tracked modes of the parent case are matched to the modes of the case by the modal assurance
criterion of mass-normalized shapes, with an optimal one-to-one assignment (`linear_sum_assignment`), so
crossings and the near-degenerate upper/lower span pairs keep their identity. Where the DOF counts
differ (a mesh sweep) the match is by classification (kind, order, span), then by frequency. A match
below MAC_LOST means the mode left the computed window: it is lost from there on.

Nomenclature: phi (n_modes, n_dof) shapes, M phi their mass-weighted shapes ("mshapes"), p the parent
case, c the case; sel (n_track,) the case's mode index per tracked mode (-1: lost).
"""

from __future__ import annotations

import numpy as np

MAC_LOST = 0.5  # below this MAC a tracked mode counts as lost (it left the computed modes)


def mac_matrix(parent: dict, case: dict, rows: np.ndarray) -> np.ndarray:
    """(len(rows), n_case_modes) match scores of the parent's modes `rows` with the case's modes.

    Same mesh: MAC_ij = |(phi_p^H M_c phi_c)(phi_c^H M_p phi_p)|, the usual MAC when the mass matrices
    are equal, insensitive to a change of mass scale between the cases and to the phase of complex
    (running-belt) shapes. Different meshes: 1 for the same (kind, order, span), plus a small
    1e-3 / (1 + |f_p - f_c|) that prefers the nearer frequency."""
    if parent["shapes"].shape[1] == case["shapes"].shape[1]:
        return np.abs((np.conj(parent["shapes"][rows]) @ case["mshapes"].T)
                      * (parent["mshapes"][rows] @ np.conj(case["shapes"]).T))
    m = len(case["frequency"])
    M = np.zeros((len(rows), m))
    for a, j in enumerate(rows):
        for b in range(m):
            same = (parent["kind"][j] == case["kind"][b] and parent["order"][j] == case["order"][b]
                    and parent["span"][j] == case["span"][b])
            M[a, b] = (1.0 if same else 0.0) + 1e-3 / (1.0 + abs(parent["frequency"][j] - case["frequency"][b]))
    return M


def first_selection(n_track: int, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    """(sel, mac) of the first tracked case: its first n_track modes (-1 past its n_modes), MAC 1."""
    sel = np.arange(n_track) if n_modes >= n_track else np.r_[np.arange(n_modes), np.full(n_track - n_modes, -1)]
    return sel, np.where(sel >= 0, 1.0, np.nan)


def match_modes(parent: dict, case: dict, n_track: int) -> tuple[np.ndarray, np.ndarray]:
    """(sel, mac): for each of the n_track tracked modes, the case's mode that continues it (-1: lost) and
    its match score. parent["sel"] is the parent's own selection; a mode the parent had lost stays lost."""
    from scipy.optimize import linear_sum_assignment

    prev = parent["sel"]
    alive = np.flatnonzero(prev >= 0)
    M = mac_matrix(parent, case, prev[alive])
    rows, cols = linear_sum_assignment(-M)
    sel = np.full(n_track, -1, dtype=np.int64)
    macs = np.full(n_track, np.nan)
    for r, col in zip(rows, cols):
        if M[r, col] >= MAC_LOST:  # else the mode left the computed window: lost from here on
            sel[alive[r]] = col
            macs[alive[r]] = M[r, col]
    return sel, macs
