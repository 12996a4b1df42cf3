"""Why a port-place design is infeasible: the bits of its ``infeasible`` column and their words.

Plain constants, apart from the kernels that set them (``place``, ``designs``), so that the readers (the
rows' schema, the reports) name them without loading numba.
"""

#: Reasons a design is infeasible (bits of the ``infeasible`` column).
REACH, CAMERA, SPACING, SHAFTS, OUTSIDE, ANGLE, CAMERA_SIDE, DOCKING = 1, 2, 4, 8, 16, 32, 64, 128
REASONS = {REACH: "instruments do not both reach every target point", CAMERA: "the camera does not see every "
           "target point", SPACING: "ports closer than the minimum spacing", SHAFTS: "shafts closer than their "
           "clearance inside the body", OUTSIDE: "arms closer than their clearance outside the body",
           ANGLE: "manipulation angle at the target centre outside its range", CAMERA_SIDE: "the camera is not "
           "between the instruments", DOCKING: "no cart pose at which the setup joints dock every arm"}
