"""The rcm_grid study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Global Isotropy Index of candidate remote-centre-of-motion locations for a serial arm
    (Locke & Patel, ICRA 2007: eqs. 5-9, Fig. 3, Table I): the paper's PA10-7C, a shipped UR5e, Panda
    or LBR iiwa 14, a URDF file or a DH table (--robot NAME|FILE, or the config's [robot]).

    For every RCM candidate the tool tip visits each point of a cube below the RCM with the tool axis
    through the RCM; the RCM-constrained IK (closed form for the PA10, damped Newton along a serpentine
    walk for any other arm) and the alternative Jacobian under the RCM constraint give the reverse
    Jacobian J_r, scaled by the rated joint speeds. GII = min sigma_min / max sigma_max over the cube
    (eq. 7); a candidate with any unreachable point (or joint limit passed) is infeasible.
    Rows: candidate_id, x_rcm_m, y_rcm_m, z_rcm_m, gii, feasible, sigma_min_m_per_s, sigma_max_m_per_s
    (metric = "standard": sigma_min_task_scaled, sigma_max_task_scaled, dimensionless), n_unreachable,
    n_singular, points_evaluated, gii_is_exact.
    """
