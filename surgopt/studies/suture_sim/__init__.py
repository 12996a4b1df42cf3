"""The suture_sim study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Suturing with one arm of the two-armed throat robot (Wei, Xu & Simaan: eqs. 2-32, Figs. 6-7).

    Five-bar, Z-theta stage through the laryngoscope fulcrum, two constant-curvature snake segments:
    8 inputs for the 6-DoF gripper pose. Each time step takes a weighted least-norm step
    dq = W^-1 J^T (J W^-1 J^T)^-1 dx (eq. 32) with closed-loop correction. Every combination of weight
    set, arm length, fulcrum position, task mode (spin | orbit_parallel | orbit_tangent), radius and
    speed is one run. Rows: run settings, step, t_s, q1_rad..q8_rad (q3 in mm), q1_norm..q8_norm
    (|q_i / q_imax|), pos_err_mm, rot_err_deg. Ends with the joint ranges of the weight sets side by side.
    """
