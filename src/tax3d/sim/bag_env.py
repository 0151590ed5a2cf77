"""The HangBag scene: the procedural bag, the hook on its pole, the same grippers and controller as HangProcCloth."""

from __future__ import annotations

import numpy as np

from tax3d.sim.bag import build_bag, load_bag, parse_bag_params
from tax3d.sim.env import HangClothEnv, SceneState, mesh_file
from tax3d.sim.hook import goal_position, hook_cloud, load_hook
from tax3d.sim.integrity import bag_figures, intact
from tax3d.sim.success import bag_success


class HangBagEnv(HangClothEnv):
    """HangClothEnv with the bag for the cloth and the hook for the hanger; `mesh` is a BagMesh."""

    scene = "bag"

    def reset(self, bag_params: dict, rot_z: float, trans) -> SceneState:
        mesh = build_bag(parse_bag_params(bag_params))
        c = self._new_world(rot_z, trans)
        self.mesh = mesh
        self.anchor_ids = load_hook(c, self.rot_z, self.trans)
        with mesh_file("bag") as obj:
            self.cloth_id = load_bag(c, self.mesh, obj)
        return self._finish_reset(self.cloth_vertices())

    def anchor_points(self) -> np.ndarray:
        return hook_cloud(self.rot_z, self.trans, with_floor=self.floor)

    def goal(self) -> np.ndarray:
        return goal_position(self.rot_z, self.trans)

    def aim_vertices(self, part: int) -> np.ndarray:
        """The strap vertices of handle `part`: the expert brings their centroid to the hook."""
        return self.mesh.handles[part]

    def judge(self, pre: np.ndarray, post: np.ndarray) -> dict:
        """The HangBag success check, plus the explosion and tunnelling figures before and after release."""
        checks = bag_success(pre, post, self.mesh.handles, self.goal())
        before, after = (bag_figures(v, self.mesh.local, self.mesh.faces, self.rot_z, self.trans) for v in (pre, post))
        checks["integrity"] = {"before": before, "after": after, "intact": intact(before) and intact(after)}
        return checks
