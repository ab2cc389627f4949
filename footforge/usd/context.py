"""The object threaded through the USD exporter: the compiled model, its pose, the stage, names.

The exporter reads the *compiled* MuJoCo model (not the MJCF text): masses, inertial frames, mesh
vertices and joint frames are then exactly what MuJoCo simulates, after its own mesh recentring
and inertia diagonalisation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from pxr import Sdf, Tf, Usd


@dataclass(frozen=True)
class Unsupported:
    """A MuJoCo feature the USD stage does not carry (or carries approximately)."""

    element: str
    """The MJCF element, e.g. "joint 'LF_foot/front_arch'"."""
    feature: str
    """What is lost, with its value and unit."""
    handling: str
    """"dropped", "approximated: ..." or "recorded in customData only"."""

    def as_dict(self) -> dict:
        return {"element": self.element, "feature": self.feature, "handling": self.handling}


@dataclass
class ExportContext:
    model: mujoco.MjModel
    data: mujoco.MjData
    """Kinematics at the exported pose (the model's home keyframe)."""
    keyframe: str | None
    """The pose's keyframe; None for qpos0."""
    stage: Usd.Stage
    root: Sdf.Path
    """The default prim; every body is a direct child (a flat articulation, as Isaac expects)."""
    joints_scope: Sdf.Path | None = None
    """Where joints (and loop closures) go."""
    body_paths: dict[int, Sdf.Path] = field(default_factory=dict)
    """MuJoCo body id -> its prim; the world body maps to a static `world` Xform."""
    unsupported: list[Unsupported] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def child_path(self, parent: Sdf.Path, name: str) -> Sdf.Path:
        """A valid, unused prim path under `parent` for a MuJoCo name (which may hold '/')."""
        base = Tf.MakeValidIdentifier(name or "unnamed")
        path, n = parent.AppendChild(base), 1
        while self.stage.GetPrimAtPath(path):
            n += 1
            path = parent.AppendChild(f"{base}_{n}")
        return path

    def lose(self, element: str, feature: str, handling: str = "dropped") -> None:
        self.unsupported.append(Unsupported(element, feature, handling))


def mj_name(model: mujoco.MjModel, obj: mujoco.mjtObj, index: int, fallback: str) -> str:
    name = mujoco.mj_id2name(model, obj, index)
    return name if name else f"{fallback}_{index}"


Pose = tuple[np.ndarray, np.ndarray]
"""(position, wxyz quaternion)."""
IDENTITY_QUAT = np.array([1.0, 0.0, 0.0, 0.0])


def mul_pose(a: Pose, b: Pose) -> Pose:
    """Pose a * pose b (MuJoCo's mju_mulPose)."""
    pos, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_mulPose(
        pos, quat, np.asarray(a[0], float), np.asarray(a[1], float), np.asarray(b[0], float), np.asarray(b[1], float)
    )
    return pos, quat


def neg_pose(a: Pose) -> Pose:
    """The inverse pose (MuJoCo's mju_negPose)."""
    pos, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_negPose(pos, quat, np.asarray(a[0], float), np.asarray(a[1], float))
    return pos, quat
