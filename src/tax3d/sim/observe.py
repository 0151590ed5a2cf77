"""The deformable as depth cameras see it at the start: the visible surface, a consumer depth camera's noise, and each
observed point's goal taken from the surface point it came from (what a point tracker gives for real demonstrations).

PyBullet's tiny renderer draws a soft body from its mesh file, unscaled at the origin, until the first simulation
step, and the episode's start is before that step. So each observation renders, in a world of its own, the floor,
the anchor, the grippers and the deformable's current surface as a rigid visual mesh: its segmentation says which
pixels see the deformable first. A ray through each such pixel's centre hits the mesh at the observed surface point;
its z-depth, with the noise added, is the pixel's depth, and tax3d.camera.depth_to_cloud turns the image into the
cloud. The hit triangle's barycentric weights carry the vertices' goals to the point.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import pybullet

from tax3d.camera import depth_to_cloud
from tax3d.geometry import nearest_rows
from tax3d.options import NonNegative, Positive
from tax3d.sim.anchor import SCALE, add_floor, load_anchor
from tax3d.sim.camera import PROJECTION, opengl_camera, render_image
from tax3d.sim.env import GRIPPER_RADIUS
from tax3d.sim.hook import load_hook

# Named camera placements about the deformable's starting centroid: (yaw, pitch) in degrees as PyBullet's
# computeViewMatrixFromYawPitchRoll takes them (yaw 0: the camera on the -y side, the anchor's, looking along +y).
VIEWS = {"front": (0.0, -30.0), "front-left": (-40.0, -30.0), "front-right": (40.0, -30.0), "back": (180.0, -30.0)}
# The scene's sizes are metres scaled by 10 (docs/reference.md, HangProcCloth scene): a scene unit is 0.1 m.
UNITS_PER_METRE = SCALE
# Axial noise of a structured-light depth camera (Kinect), sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 metres at depth z
# metres (Nguyen, Izadi and Lovell, "Modeling Kinect Sensor Noise for Improved 3D Reconstruction and Tracking",
# 3DIMPVT 2012): the deviation grows with the square of the distance.
NOISE_BASE, NOISE_QUADRATIC, NOISE_OFFSET = 0.0012, 0.0019, 0.4
CAMERA_STREAM = 0x63616D  # the camera noise's own random stream beside the episode's
View = Literal["front", "front-left", "front-right", "back"]


@dataclass
class CameraSpec:
    """The simulated depth cameras: where they stand, their images, their noise."""

    views: tuple[View, ...] = ("front",)
    """named placements about the deformable's starting centroid: front (the anchor's side), front-left, front-right,
    back; several cameras' clouds are joined"""
    distance: Annotated[float, Positive] = 10.0
    """each camera's distance from the deformable's starting centroid, scene units (10: one metre)"""
    size: Annotated[int, Positive] = 200
    """image width and height in pixels (the reference camera's projection: 106 by 90 degrees)"""
    noise_base: Annotated[float, NonNegative] = NOISE_BASE
    """depth noise sigma = base + quadratic (z - offset)^2, z and sigma in metres: the constant term (0: with
    quadratic 0, no noise)"""
    noise_quadratic: Annotated[float, NonNegative] = NOISE_QUADRATIC
    """the term that grows with the squared depth, per metre"""
    noise_offset: Annotated[float, NonNegative] = NOISE_OFFSET
    """the depth, metres, from which the quadratic term grows"""

    def sigma(self, z: np.ndarray) -> np.ndarray:
        """The depth noise's standard deviation at z-depth z, both in scene units."""
        metres = np.asarray(z) / UNITS_PER_METRE
        return UNITS_PER_METRE * (self.noise_base + self.noise_quadratic * (metres - self.noise_offset) ** 2)


@dataclass
class Observation:
    points: np.ndarray  # (N, 3) observed points, world frame, noise included
    surface: np.ndarray  # (N, 3) the surface points they came from, noise-free
    faces: np.ndarray  # (N,) the mesh triangle each one lies on
    weights: np.ndarray  # (N, 3) its barycentric weights on that triangle's vertices

    def carry(self, vertex_values: np.ndarray, mesh_faces: np.ndarray) -> np.ndarray:
        """Per-vertex values (V, 3), such as the vertices' goals, at the observed surface points (N, 3)."""
        corners = vertex_values[mesh_faces[self.faces]]  # (N, 3 corners, 3)
        return np.einsum("nc,ncd->nd", self.weights, corners)


def observe(env, spec: CameraSpec, rng: np.random.Generator) -> Observation:
    """The deformable of `env` (in its current state) as the cameras of `spec` see it, with noise from `rng`."""
    vertices = env.cloth_vertices()
    faces = np.asarray(env.mesh.faces)
    client, body = _render_world(env, vertices, faces)
    parts = []
    for name in spec.views:
        view = pybullet.computeViewMatrixFromYawPitchRoll(
            vertices.mean(0).tolist(), spec.distance, *VIEWS[name], 0.0, 2
        )
        _, seg = render_image(client, view, PROJECTION, spec.size)
        k, pose = opengl_camera(view, PROJECTION, spec.size, spec.size)
        k[:2, 2] -= 0.5  # rays through the pixels' centres
        parts.append(_camera_points(seg == body, k, pose, vertices, faces, spec, rng))
    return Observation(*(np.concatenate([p[i] for p in parts]) for i in range(4)))


def _camera_points(mask, k, pose, vertices, faces, spec: CameraSpec, rng):
    v, u = np.nonzero(mask)
    rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones(len(u))], axis=1) @ pose[:3, :3].T
    z, face, weights = first_hits(pose[:3, 3], rays, vertices[faces])
    hit = np.isfinite(z)  # a silhouette pixel's centre ray may pass beside the mesh: such a pixel is left out
    depth = np.full(mask.shape, np.nan)
    depth[v[hit], u[hit]] = z[hit] + spec.sigma(z[hit]) * rng.standard_normal(int(hit.sum()))
    seen = np.zeros_like(mask)
    seen[v[hit], u[hit]] = True
    if not seen.any():
        empty = np.zeros((0, 3))
        return empty, empty, np.zeros(0, dtype=int), empty
    points = depth_to_cloud(depth, seen, k, pose)
    surface = pose[:3, 3] + rays[hit] * z[hit, None]
    return points, surface, face[hit], weights[hit]


def first_hits(origin: np.ndarray, rays: np.ndarray, triangles: np.ndarray, chunk: int = 512):
    """The first triangle each ray origin + t ray (t > 0) meets: t (inf where none), the triangle, the barycentric
    weights of the hit point. Moeller and Trumbore's ray-triangle test, all triangles at once."""
    a, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    s = origin - a  # (F, 3): one origin for every ray
    q = np.cross(s, e1)
    t_all, face, weights = np.full(len(rays), np.inf), np.zeros(len(rays), dtype=int), np.zeros((len(rays), 3))
    for start in range(0, len(rays), chunk):
        d = rays[start : start + chunk, None, :]  # (n, 1, 3)
        p = np.cross(d, e2)  # (n, F, 3)
        det = np.einsum("nfk,fk->nf", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            b1 = np.einsum("nfk,fk->nf", p, s) * inv
            b2 = np.einsum("nk,fk->nf", d[:, 0], q) * inv
            t = np.einsum("fk,fk->f", e2, q) * inv
        ok = (np.abs(det) > 1e-12) & (b1 >= -1e-9) & (b2 >= -1e-9) & (b1 + b2 <= 1 + 1e-9) & (t > 0)
        t = np.where(ok, t, np.inf)
        best = t.argmin(axis=1)
        rows = np.arange(len(best))
        t_all[start : start + chunk] = t[rows, best]
        face[start : start + chunk] = best
        w1, w2 = b1[rows, best], b2[rows, best]
        weights[start : start + chunk] = np.stack([1 - w1 - w2, w1, w2], axis=1)
    return t_all, face, weights


_WORLD: dict = {}


def _render_world(env, vertices: np.ndarray, faces: np.ndarray) -> tuple[int, int]:
    """This process's rendering world, rebuilt as the scene of `env` with the deformable as a rigid visual mesh."""
    if "client" not in _WORLD:
        _WORLD["client"] = pybullet.connect(pybullet.DIRECT)
    c = _WORLD["client"]
    pybullet.resetSimulation(physicsClientId=c)
    if env.floor:
        add_floor(c)
    (load_hook if env.scene == "bag" else load_anchor)(c, env.rot_z, env.trans)
    grippers, _ = env.gripper_state()
    for position in grippers:
        look = pybullet.createVisualShape(pybullet.GEOM_SPHERE, radius=GRIPPER_RADIUS, physicsClientId=c)
        pybullet.createMultiBody(0, -1, look, basePosition=position.tolist(), physicsClientId=c)
    both_sides = np.concatenate([faces, faces[:, ::-1]])  # the tiny renderer culls faces seen from behind
    look = pybullet.createVisualShape(
        pybullet.GEOM_MESH, vertices=vertices.tolist(), indices=both_sides.ravel().tolist(), physicsClientId=c
    )
    return c, pybullet.createMultiBody(0, -1, look, physicsClientId=c)


def camera_seed(task: str, split: str, cloth_index: int) -> np.random.Generator:
    """The noise of one cloth's camera demos: the same for every demo of a cloth (a multimodal pair sees one cloud)
    and for every run."""
    return np.random.default_rng(np.random.SeedSequence([zlib.crc32(task.encode()), zlib.crc32(split.encode()),
                                                         cloth_index, CAMERA_STREAM]))


def camera_demo(env, demo: dict, spec: CameraSpec, rng: np.random.Generator) -> dict:
    """A mesh demo as the cameras see its deformable at the start: `env` is reset to the demo's start; action_pc
    becomes the observed points, flow their goals (the demo's vertex goals at the surface points they came from)
    less them, and each gripper holds the observed point nearest its grasped vertex. The other keys stay."""
    start = env.cloth_vertices()
    if start.shape != demo["action_pc"].shape or not np.allclose(start, demo["action_pc"], atol=1e-5):
        raise RuntimeError("the scene's deformable at reset is not the demo's action_pc; expected the demo's start")
    seen = observe(env, spec, rng)
    if len(seen.points) == 0:
        raise RuntimeError(f"cameras {', '.join(spec.views)} see none of the deformable")
    goals = seen.carry(demo["action_pc"] + demo["flow"], np.asarray(env.mesh.faces))
    out = {k: v for k, v in demo.items() if k not in ("action_pc", "flow", "action_seg", "anchors")
           and not k.startswith("traj_")}
    out.update(action_pc=seen.points, flow=goals - seen.points, action_seg=np.ones(len(seen.points)))
    if "anchors" in demo:
        out["anchors"] = {
            g: {"pos": held["pos"], "vertices": nearest_rows(seen.points, demo["action_pc"][list(held["vertices"])])}
            for g, held in demo["anchors"].items()
        }
    return out
