"""Raven IV arm: a spherical RCM mechanism (links alpha, beta) carrying a tool with a wrist.

Source: Z. Li, D. Glozman, D. Milutinovic, J. Rosen, "Maximizing dexterous
workspace and optimal port placement of a multi-arm surgical robot", ICRA 2011
(Raven IV), Table I (standard DH) and joint ranges. Angles in rad, lengths mm.

Standard DH rows (theta, d, a, alpha) per arm, joint variables theta1, theta2,
theta3, d4, theta5, theta6:

    left arms (1, 3)                         right arms (2, 4)
    theta1,            0, 0,  pi - alpha     pi - theta1,        0, 0,  pi - alpha
    -theta2,           0, 0,  -beta          theta2,             0, 0,  -beta
    pi/2 - theta3,     0, 0,  0              3 pi/2 + theta3,    0, 0,  0
    0,                 d4, 0, -pi/2          0,                  d4, 0, -pi/2
    pi/2 - theta5,     0, a5, pi/2           pi/2 - theta5,      0, a5, pi/2
    pi/2 + theta6,     0, 0,  -pi/2          pi/2 + theta6,      0, 0,  -pi/2

(Table I lists rows 5-6 for the left arm only; the right arm uses the same
wrist rows.) Ranges (Table I): theta2 in [20, 140] deg, theta3 and theta6 in
[-86, 86] deg, d4 in [0, 250] mm; theta1 and theta5 unlisted (unlimited).

The kernels read the theta columns of rows 1-3 from ``DH_THETA_ROWS`` below
(theta_i = sign * q_i + offset) and the ranges from the constants; the rest
of each row (d, a, alpha) is fixed by the mechanism and written out in
``surgopt.kinematics.raven``.
"""
from __future__ import annotations

import math

#: DH theta of rows 1-3 as (sign, offset rad) applied to theta1, theta2, theta3, per arm side (Table I).
DH_THETA_ROWS = {
    "left": ((1.0, 0.0), (-1.0, 0.0), (-1.0, math.pi / 2)),
    "right": ((-1.0, math.pi), (1.0, 0.0), (1.0, 1.5 * math.pi)),
}
THETA2_RANGE_DEG = (20.0, 140.0)
#: The Raven II's shoulder software stops (uw-biorobotics/raven2, include/raven/defines.h:
#: SHOULDER_MIN_LIMIT 0 deg, SHOULDER_MAX_LIMIT 90 deg), measured from the Raven II's own kinematic zero.
#: The Raven IV paper lists no theta1 range; this is a candidate value, not the paper's (the sweep's
#: ``geometry.theta1_range_deg``, with ``theta1_zero_toward`` naming where our theta1 = 0 points).
THETA1_RANGE_RAVEN_II_DEG = (0.0, 90.0)
THETA3_RANGE_DEG = (-86.0, 86.0)
THETA6_RANGE_DEG = (-86.0, 86.0)
D4_RANGE_MM = (0.0, 250.0)
REFERENCE_PLANE_DEPTH_MM = 150.0  # Sec. III-A
