"""Port-place's kernels (issue 53: one folder, not eight modules loose in ``kinematics/``): the per-port, per-pair
and per-design kernels (``place``, ``designs``, the infeasibility bits ``reasons``), serial arms holding the RCM in
software (``serial``), the patient cart's setup joints (``suj``: forward and inverse kinematics in plain Python;
``suj_batch``: the same inverse jitted over many poses; ``si_docking``: the Si cart's), and the links' clearances
(``capsules``). Numba kernels and the numpy helpers that pack their inputs; no study, config or store here."""
