"""Turntables (``gonio render --orbit``, ``orbit =`` in a batch plan): a scene turned
by one frame's angle, the camera about its target or every object about the same axis."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..names import pick
from .mesh import rotation_matrix
from .scene_types import Scene


#: What a turntable turns (``gonio render --orbit``, ``orbit =`` in a batch plan):
#: ``camera`` moves the eye about the target (the lights stay with the world, so
#: highlights and colours shift as on a gonioreflectometer); ``object`` turns every
#: object about the same axis under a fixed camera and fixed lights.
ORBITS = ("camera", "object")


def axis_rotation(axis, angle_deg: float) -> np.ndarray:
    """(3, 3) right-handed rotation by ``angle_deg`` about ``axis`` (Rodrigues' formula,
    R = I + sin θ K + (1 − cos θ) K², K the cross-product matrix of the unit axis)."""
    k = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    t = np.radians(angle_deg)
    return np.eye(3) + np.sin(t) * kx + (1.0 - np.cos(t)) * (kx @ kx)


def euler_xyz_deg(r: np.ndarray) -> np.ndarray:
    """(3,) XYZ Euler angles in degrees of a rotation, the inverse of
    :func:`gonio_cli.render.mesh.rotation_matrix` (R = Rz · Ry · Rx); at gimbal lock
    (|R[2, 0]| = 1) the x angle is 0 and z carries the rest."""
    sy = -float(np.clip(r[2, 0], -1.0, 1.0))
    ay = np.arcsin(sy)
    if abs(sy) < 1.0 - 1e-12:  # away from gimbal lock (cos y > ~1e-6)
        ax, az = np.arctan2(r[2, 1], r[2, 2]), np.arctan2(r[1, 0], r[0, 0])
    else:
        ax, az = 0.0, np.arctan2(-r[0, 1], r[1, 1])
    return np.degrees([ax, ay, az])


def orbit(scene: Scene, frame: int, frames: int, mode: str = "camera") -> Scene:
    """Frame ``frame`` of an ``frames``-step turntable: the scene turned by
    360°·frame/frames about its up axis (the camera's ``up`` through its ``target``).

    ``mode`` (a key of :data:`ORBITS`): ``camera`` turns the eye (and its up vector);
    ``object`` turns each object the other way about the same axis (its placement
    R·(s⊙p)+t becomes Q·R·(s⊙p) + Q·(t − target) + target), so the camera sees the
    object's far side come round in the same direction.
    """
    pick(ORBITS, mode, "orbit")
    cam = scene.camera
    angle = 360.0 * frame / frames
    if mode == "camera":
        q = axis_rotation(cam.up, angle)
        camera = replace(cam, eye=cam.target + q @ (cam.eye - cam.target), up=q @ cam.up)
        return replace(scene, camera=camera)
    q = axis_rotation(cam.up, -angle)
    objects = [replace(o, rotate_deg=euler_xyz_deg(q @ rotation_matrix(o.rotate_deg)),
                        translate=cam.target + q @ (o.translate - cam.target))
               for o in scene.objects]
    return replace(scene, objects=objects)
