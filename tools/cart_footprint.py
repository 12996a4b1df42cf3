"""The patient cart's footprint on the floor from its own mesh (issue 54: "the cart's footprint and column").

Run:  python tools/cart_footprint.py /work/.mirror/shashank3199+dvrk_urdf/repo

Reads ``suj_description/meshes/Classic/base_link.stl`` (the Classic patient cart: its wheeled base and its column)
from shashank3199/dvrk_urdf at COMMIT (placed by ``patient_cart.classic.urdf.xacro`` at (0, 0, 0.167458) in its
world frame, whose x and y are the dVRK's cart world frame's: the setup joints' mounts agree, see below) and prints
the mesh's sha256 and the rectangle its vertices span on the floor (x, y, m, the cart's world frame) and the column's
above the base, for ``robots/dvrk/platforms.py``. Also checks the frames agree: PSM1's and the ECM's setup-joint
mounts in the xacro equal the dVRK JSON's world_origin_to_SUJ moved by the column row's A (kinematics files).
"""
from __future__ import annotations

import hashlib
import io
import subprocess
import sys

import numpy as np

COMMIT = "f4e68a8c"
MESH = "suj_description/meshes/Classic/base_link.stl"
BASE_LINK_Z_M = 0.167458  # patient_cart.classic.urdf.xacro: world -> base_link
#: The base's top: below it the wheeled base spans the whole footprint; above it only the column (m, world).
BASE_TOP_M = 0.37


def main(repo: str) -> None:
    import trimesh

    data = subprocess.run(["git", "-C", repo, "show", f"{COMMIT}:{MESH}"], capture_output=True, check=True).stdout
    mesh = trimesh.load(io.BytesIO(data), file_type="stl")
    v = mesh.vertices + [0.0, 0.0, BASE_LINK_Z_M]
    column = v[v[:, 2] > BASE_TOP_M]
    print(f"{MESH} at {COMMIT}: sha256 {hashlib.sha256(data).hexdigest()}, {len(mesh.faces)} faces")
    print(f"  floor footprint x [{v[:, 0].min():.3f}, {v[:, 0].max():.3f}] y [{v[:, 1].min():.3f}, "
          f"{v[:, 1].max():.3f}] m; height {v[:, 2].min():.3f} .. {v[:, 2].max():.3f} m")
    print(f"  column above {BASE_TOP_M} m: x [{column[:, 0].min():.3f}, {column[:, 0].max():.3f}] y "
          f"[{column[:, 1].min():.3f}, {column[:, 1].max():.3f}] m")
    # the frames: the xacro's PSM1 mount (-0.1912, -0.1016) and ECM mount (0, 0.0896) on base_link; the JSON's
    # world_origin_to_SUJ (-0.1016, -0.1016) turned by pi, (0, 0) turned by pi/2, plus the column row's A = 0.0896
    for name, xacro, json_xy, turn in (("PSM1", (-0.1912, -0.1016), (-0.1016, -0.1016), np.pi),
                                       ("ECM", (0.0, 0.0896), (0.0, 0.0), np.pi / 2)):
        moved = np.add(json_xy, 0.0896 * np.array([np.cos(turn), np.sin(turn)]))
        print(f"  {name}: xacro mount {xacro}, JSON world_origin_to_SUJ + column A {tuple(np.round(moved, 4))}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "/work/.mirror/shashank3199+dvrk_urdf/repo")
