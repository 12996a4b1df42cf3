"""The raven_sweep study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Raven IV port placement and link design (Li, Glozman, Milutinovic, Rosen, ICRA 2011: eqs. 1-43,
    Table II, Figs. 4, 6-8).

    For every design (alpha, beta, phi_x, phi_y, phi_z, bx, by, Iso_min) the common workspace of all arms
    on a plane 150 mm below the ports: a point belongs to an arm when its tool axis can point there with
    theta2 in the range narrowed by Iso_min, d4 <= 250 mm and the shoulder joint theta1 inside
    geometry.theta1_range_deg (by default the Raven II's [0, 90] deg; [-180, 180]: unlimited). Rows: the
    eight parameters, area_cm2, perimeter_cm, zeta_cm (eq. 33), iso_sum, iso_mean, iso_area_cm2,
    iso_min_actual, n_points, cost (eq. 43), source (grid | refine). Ends with the top designs and the rank of the paper's optimum.
    """
