"""The rcm_track study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Trajectory tracking at candidate RCM locations (Locke & Patel, ICRA 2007, Sec. IV, Table I's
    "Max error" column, Figs. 4-6).

    For each RCM candidate of an rcm-grid config (robot, workspace, candidates) the tool tip follows the
    paper's helical test path from the top to the bottom of the workspace cube (2.5 turns, 10 s, cubic
    time scaling: 364 mm at 36.4 mm/s mean, 54.6 mm/s peak), with the tool through the RCM. The
    reference joints come from the RCM-constrained IK; a joint-level proportional controller runs at
    1 kHz, each joint's commanded velocity saturated at its rated speed (the GII's Q), optionally through
    a first-order velocity lag ([track] section). The gain is not in the paper: it is calibrated so that
    the best candidate's maximum error is the paper's 5.1 mm (docs/reproduction.md).
    Rows: candidate_id, x_rcm_m, y_rcm_m, z_rcm_m, gii, feasible, max/mean tip and RCM errors (mm), peak
    |qdot|/qdot_max per active joint, saturated_s, and per-step traces for the candidates in track.keep.
    """
