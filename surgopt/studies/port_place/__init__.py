"""The port_place study: its declaration (study.py), config, figures and report page.

``HELP``, the study command's help, is here so that ``surgopt --help`` lists the studies without importing them
(numpy, pydantic, their configs).
"""

HELP = """Port placement for the da Vinci Research Kit on a patient: two or three PSMs and the ECM, docked by the patient cart.

    Example: surgopt port-place   (the dVRK example: a dome patient, the Classic cart, the arms' links checked)

    Example: surgopt port-place my_patient.toml cart.distance_mm=[900,1200] --dry-run   (a config of one's own
    changes only what it names; --dry-run first says the size, time and memory)

    Frame: the patient's, in mm, on the table top: x lateral (the patient's left +x), y toward the head,
    z anterior (up).

    Every assignment of the instrument ports (robot.instrument_count = 2 or 3) and the camera port to candidate
    sites is one design: each instrument's reach (RCM inverse kinematics within the joint limits), dexterity,
    manipulation angle (45-75 deg, Hanna 1997), azimuth imbalance, the camera's view from inside the body, port
    spacing, shaft clearances, a cost, and why a design is infeasible. With the cart (cart.model = auto: the
    Classic cart for the dVRK's Classic arms; none: docking assumed) every arm's setup joints are solved at each
    cart pose of a grid around the table, and a design is feasible only where one pose docks every arm with its
    links clear of each other, the patient and the table. The summary ranks the feasible designs by cost.

    Then: surgopt report (the run's page); surgopt export KEY --design ID --format dvrk (the set-up, joint by
    joint), dvrk-suj-fixed and dvrk-console (the files a dVRK loads), slicer (3D Slicer markups) or ports (CSV). A
    [given_layout] (each arm's port by a landmark and offsets) is scored beside the answer, against the stored
    run in seconds. A CT's patient: a patient file (configs/patients/openhelp.toml: its wall, landmarks and organs,
    the organs obstacles the shafts must not cross) with a case over it. Other arms: cart.model = si with the
    Si's PSMs and ECM (the docking roll fields then the yaw off psi*), an RCM arm from a DH table or URDF
    ([robot.instrument_file], [robot.camera_file]), a serial arm keeping the RCM in software
    ([robot.instrument_serial], [robot.camera_serial]). A 3-PSM enumeration runs to 10^8 designs:
    rows_stored = feasible keeps only the feasible rows."""
