"""The port_place study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Port placement for the da Vinci Research Kit on a patient: two or three PSMs and the ECM.

    Candidate ports on an insufflated abdomen (a half-ellipsoid or superquadric dome, or a closed mesh), a
    target inside it (sphere, ellipsoid or box sampled at a spacing, a points file, or a closed mesh). Every
    assignment of the instrument ports (robot.instrument_count = 2 or 3) and the camera port is one design:
    reach of each instrument (RCM inverse kinematics within the joint limits), common reach, dexterity,
    manipulation angle (45-75 deg, Hanna 1997), azimuth imbalance, camera coverage, port spacing, shaft and arm
    clearances, cost, and why a design is infeasible (a bit mask). With the patient cart ([cart]; the Classic
    cart by default for the dVRK's arms) each arm's setup joints are solved at every site and cart pose of a
    grid around the table (or one given, or searched), and a design is feasible only where one pose docks every
    arm with every arm's links (setup joints' and its own, capsules) clear of each other, the patient and the
    table (constraints.min_link_clearance_mm, mm, 0 by default; off: docking alone); the closing report's best
    layout may turn a PSM's docking about its shaft to clear them. cart.model=si docks the Si's PSMs and ECM
    (robot.instrument_arm=dvrk_psm_si, robot.camera_arm=dvrk_ecm_si) at the one orientation its setup joints
    give nearest the aim, the arms' own yaw and pitch absorbing the rest (its links measured by the report, not
    in feasible). `surgopt export KEY --design ID --format dvrk` writes the set-up a dVRK loads. Rows: one per
    design. The summary ranks feasible designs by cost and checks the best against the clinical numbers.
    A 3-PSM enumeration runs to 10^8 designs and more: rows_stored=feasible keeps only the feasible designs'
    rows. Any RCM arm from a DH table or URDF ([robot.instrument_file], [robot.camera_file]), or a serial arm
    keeping the RCM in software ([robot.instrument_serial], [robot.camera_serial]: a PA10, UR5e, Panda, iiwa or
    any DH/URDF arm, its base standing beside the port) in place of the dVRK's."""
