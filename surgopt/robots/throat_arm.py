"""One robotic surgical arm of the two-armed throat slave (Wei, Xu & Simaan 2007).

Chain: planar five-bar (q1, q2) -> passive universal joint at P_U -> Z-theta
stage (q3 translation, q4 rotation) carrying the DDU holder through the
fulcrum P_F (laryngoscope seal) -> snake-like unit SLU (theta_L, delta) ->
PMU modelled as a second snake segment (phi_L', psi) -> gripper.
Lengths in mm, angles in rad.

Sources and choices
-------------------
[WXS07] W. Wei, K. Xu, N. Simaan, "A compact two-armed slave manipulator for
        minimally invasive surgery of the throat", BioRob 2006 / 2007.
  - five-bar links l1..l6 = 60, 60, 110, 90, 80, 180 mm (Table I); l1 is the
    ground link (actuators at y = -+l1/2), l5 and l2 the actuated links
    (eqs. 3, 4), l4 and l3 the distal links, l6 the extension of l3 to the
    end-effector P_U (eq. 6).
  - snake-arm (DDU holder) lengths 550 and 800 mm; holder diameter 4.8 mm.
  - start pose [1.4522, 2.4707, 50, 0, pi/2, -pi/3, 0, -pi/3] (Sec. V-B).
  - theta_0 = phi_0 = pi/2: a straight segment has theta_L = pi/2 (Simaan's
    notation, [20, 21] of the paper).
Not given by the paper, chosen here (docs/reproduction.md says why):
  - SLU length 25 mm and PMU length 12 mm: multi-backbone segments of a
    4.8 mm holder that bend through +-90 deg reach a few tens of mm, enough
    for a 50 mm x 100 mm cylindrical field together with the five-bar and
    Z-theta stage.
  - the five-bar assembly branch: C on the right of the directed line D -> B. At the paper's start pose
    the other branch ("left", this model's default before 2026-12) closes the loop as a crossed,
    self-intersecting pentagon (edge A1-D crosses edge C-B), which no physical five-bar can be built
    as; it is refused. The two branches give joint ranges 2-5x apart under W1 (docs/reproduction.md).
  - the fulcrum P_F: on the snake arm's axis at the start pose, 150 mm
    before the holder tip (the seal near the laryngoscope's distal end);
    ``fulcrum_to_tip_mm`` moves it.
  - joint ranges, each its own [lower, upper] (JOINT_RANGES): q1, q2 in
    [-pi, pi] (rotary actuators), q3 in [-100, 100] mm (stage stroke), q4 in
    [-2 pi, 2 pi] (the stage turns the holder a full turn either way),
    theta_L and phi_L' in [0, pi] (bends up to +-90 deg; pi/2 is straight),
    delta and psi in [-pi, pi]. The PMU starts at phi_L' = 0, exactly at its
    lower limit (the paper's start pose). Q_MAX (q_imax of the paper's
    |q_i / q_imax| in Fig. 7) is kept for that normalisation only.
"""
from __future__ import annotations

import math
from enum import IntEnum

JOINT_NAMES = ("q1", "q2", "q3", "q4", "theta_L", "delta", "phi_L", "psi")
JOINT_UNITS = ("rad", "rad", "mm", "rad", "rad", "rad", "rad", "rad")

FIVE_BAR_LINKS_MM = (60.0, 60.0, 110.0, 90.0, 80.0, 180.0)  # l1..l6, Table I
SNAKE_ARM_LENGTHS_MM = (550.0, 800.0)
SLU_LENGTH_MM = 25.0
PMU_LENGTH_MM = 12.0
FULCRUM_TO_TIP_MM = 150.0
START_POSE = (1.4522, 2.4707, 50.0, 0.0, math.pi / 2, -math.pi / 3, 0.0, -math.pi / 3)
Q_MAX = (math.pi, math.pi, 100.0, 2 * math.pi, math.pi, math.pi, math.pi, math.pi)
#: Each joint's range (lower, upper), in the joint's unit (rad; q3 mm): what the limit check holds a run to.
JOINT_RANGES = ((-math.pi, math.pi), (-math.pi, math.pi), (-100.0, 100.0), (-2 * math.pi, 2 * math.pi),
                (0.0, math.pi), (-math.pi, math.pi), (0.0, math.pi), (-math.pi, math.pi))
FIVE_BAR_BRANCH = "right"


# The suture task modes (configs name them; the kernel takes their integer values).
class SutureMode(IntEnum):
    """How the gripper follows the suture (``throat.suture_target``); configs use the lower-case names.

    spin: the gripper spins about its own axis at a fixed point (a needle held off the axis traces
    the arc); orbit_parallel: the platform circles in its own x-y plane, orientation fixed;
    orbit_tangent: it circles in its y-z plane with its axis kept tangent to the path.
    """

    SPIN = 0
    ORBIT_PARALLEL = 1
    ORBIT_TANGENT = 2

    @property
    def config_name(self) -> str:
        return self.name.lower()


#: The config names, in kernel order.
MODE_NAMES = tuple(m.config_name for m in SutureMode)
