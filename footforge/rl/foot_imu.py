"""The passive joints of AFF and AOF, estimated on the 34-joint closed-chain foot from IMUs.

Haptic policies (BH, PH) read the passive joints of the feet they trained on: AFF's ankle pitch
and roll, AOF's as well and its front and back sole hinges. The SoftFoot-Q has no encoders; the
paper notes that its four IMUs per foot give these quantities, without saying where they sit.
This module reads them off a closed-chain foot from what IMUs measure, the orientation and
angular rate of the body each is fixed to, plus the leg's own kinematics (the orientation of
the foot's mount), with the sensors placed where the mapping is exact for rigid motions:

- Sensors on the front arch and on the back arch. AFF's pitch hinge sits on the arches' common
  axis; a rigid pitch of the whole foot by theta turns both arches by theta about the mount's y
  axis, while the arches' spread turns them by +s and -s. So
  ankle_pitch = mean of the two arches' turns about the mount's y axis (from the reference pose):
  exact for a rigid pitch, blind to the spread.
- Orientation sensors on the middle chain's links 2-4 (front half of the sole) and 6-8 (back
  half); the chain runs from the front roll link (link 1) to the back one (link 9), and AOF
  splits its sole at the middle. Relative to the pitched frame P = R_mount R_y(pitch), each link
  has turned from the reference pose by R_x(roll) R_y(.): the roll about the sole's length (AFF's
  roll axis, the line between the roll pivots), averaged over the six links, is ankle_roll. In
  the rolled frame V = P R_x(roll), the sum d of a half's link directions (each link's pin-to-pin
  axis, front to back) is the chord of that half: AOF's sole_front turns its plate about +y, so
  sole_front = atan2(d_z, -d_x) of links 2-4; sole_back turns about -y, so sole_back =
  atan2(-d_z, -d_x) of links 6-8. Both are zero when the sole lies along the pivot line (flat),
  as AOF's plates are flat at zero. One link alone will not do: on the ground the chain's inner
  and outer (padded) links zigzag by up to 7 degrees, which the three-link chord averages out;
  the end links 1 and 9 curve up to the roll links and belong to no flat plate. (So eight
  sensors where the real foot has four; a chord from two would need the links' positions.)

The reference pose for the arches and the roll is the closed chain's slack reference (its `home`
keyframe), the pose the derived feet were made from, where their passive joints are all zero.
Rates come from the same IMUs' gyroscopes (MuJoCo's body angular velocities), differenced and
projected on the same axes.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from footforge import constants as C
from footforge.errors import InputError

FRONT_LINKS, BACK_LINKS = (
    ("chain_middle_2", "chain_middle_3", "chain_middle_4"),
    ("chain_middle_6", "chain_middle_7", "chain_middle_8"),
)
"""The middle chain's links whose orientations give the front and back halves of the sole."""
IMU_BODIES = ("front_arch", "back_arch") + FRONT_LINKS + BACK_LINKS
"""The orientation sensors of each foot (body names under <LEG>_foot/); the mount's orientation
is the leg's own (the robot's kinematics)."""
ESTIMATED = ("ankle_pitch", "ankle_roll", "sole_front", "sole_back")
"""What is estimated, named as AFF's and AOF's passive joints."""


def _angle_about_y(rotation: np.ndarray) -> float:
    """theta of a rotation R_y(theta) (3x3)."""
    return float(np.arctan2(rotation[0, 2], rotation[0, 0]))


def _roll(rotation: np.ndarray) -> float:
    """rho of a rotation R_x(rho) R_y(beta) (3x3)."""
    return float(np.arctan2(rotation[2, 1], rotation[1, 1]))


def _rotation_x(angle: float) -> np.ndarray:
    """R_x(angle) (3x3), as pinocchio.utils.rotate("x", angle): numpy alone, so evaluating and
    playing on the closed chain need no model-building package."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rotation_y(angle: float) -> np.ndarray:
    """R_y(angle) (3x3), as pinocchio.utils.rotate("y", angle)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


class FootImuEstimator:
    """AFF's or AOF's passive joint angles and rates, estimated on a closed-chain robot.

    names: the passive joints to estimate, in the order a policy reads them
    (envs.anymal.Robot.passive_names of the feet it trained on, e.g. "LF_foot/ankle_pitch").

    Raises:
      InputError: a name that is not one of ESTIMATED, or a model without the IMUs' bodies or the
        `home` keyframe (not a closed-chain robot).
    """

    def __init__(self, model: mujoco.MjModel, names: Sequence[str]):
        self.names = tuple(names)
        self._legs, self._which = [], []
        for name in names:
            leg, _, joint = name.partition("_foot/")
            if leg not in C.LEGS or joint not in ESTIMATED:
                raise InputError(
                    f"cannot estimate the passive joint {name!r} on the closed chain",
                    fix=f"joints <leg>_foot/<name> with name one of {', '.join(ESTIMATED)}",
                )
            self._legs.append(C.LEGS.index(leg))
            self._which.append(ESTIMATED.index(joint))
        self._bodies = np.zeros((len(C.LEGS), 1 + len(IMU_BODIES)), int)  # mount, then the IMUs
        for i, leg in enumerate(C.LEGS):
            for k, body in enumerate(("mount",) + IMU_BODIES):
                b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{leg}_foot/{body}")
                if b < 0:
                    raise InputError(
                        f"the model has no body {leg}_foot/{body}: not a closed-chain SoftFoot-Q robot",
                        fix="run haptic policies on the `full` build",
                    )
                self._bodies[i, k] = b
        key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
        if key < 0:
            raise InputError(
                "the closed-chain model has no `home` keyframe (the feet's reference pose)",
                fix="rebuild it with `footforge build --variant full`",
            )
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, key)
        mujoco.mj_kinematics(model, data)
        # Each IMU's orientation in its mount's frame at the reference pose.
        self._reference = np.array(
            [
                [data.xmat[bodies[0]].reshape(3, 3).T @ data.xmat[b].reshape(3, 3) for b in bodies[1:]]
                for bodies in self._bodies
            ]
        )

    def leg_estimates(self, data: mujoco.MjData, leg: int) -> tuple[np.ndarray, np.ndarray]:
        """(angles, rates) of ESTIMATED for one leg (index into constants.LEGS), rad and rad/s,
        from data's body orientations and angular velocities (after mj_forward or mj_step)."""
        n_front = len(FRONT_LINKS)
        mount = data.xmat[self._bodies[leg, 0]].reshape(3, 3)
        oriented = [mount.T @ data.xmat[b].reshape(3, 3) for b in self._bodies[leg, 1:]]  # in the mount's frame
        turned = [r @ ref.T for r, ref in zip(oriented, self._reference[leg])]  # since the reference pose
        pitch = 0.5 * (_angle_about_y(turned[0]) + _angle_about_y(turned[1]))
        pitched = _rotation_y(pitch)  # P
        roll = float(np.mean([_roll(pitched.T @ link) for link in turned[2:]]))
        sole = pitched @ _rotation_x(roll)  # V, in the mount's frame
        z = [r[:, 2] for r in oriented[2:]]  # the links' lengths (local z, front to back)
        halves = (slice(0, n_front), slice(n_front, None))
        front, back = (sole.T @ np.sum(z[h], axis=0) for h in halves)
        angles = np.array([pitch, roll, np.arctan2(front[2], -front[0]), np.arctan2(-back[2], -back[0])])

        # Rates: the gyroscopes' angular velocities relative to the mount, in the mount's frame.
        omega = [mount.T @ (data.cvel[b, :3] - data.cvel[self._bodies[leg, 0], :3]) for b in self._bodies[leg, 1:]]
        y_axis = np.array([0.0, 1.0, 0.0])
        pitch_rate = 0.5 * (omega[0][1] + omega[1][1])
        x_p = pitched[:, 0]  # P's x axis, in the mount's frame
        roll_rate = float(np.mean([(w - pitch_rate * y_axis) @ x_p for w in omega[2:]]))  # the links against P
        # Each half's chord d = sum of the link directions z_i turns as d' = sum of omega_i x z_i;
        # seen from V, which turns at pitch_rate about y and roll_rate about x_p, and through atan2.
        omega_v = pitch_rate * y_axis + roll_rate * x_p
        links = list(zip(omega[2:], z))
        rates = []
        for h, sign in zip(halves, (1.0, -1.0)):
            d = np.sum(z[h], axis=0)
            d_dot = np.sum([np.cross(w, zi) for w, zi in links[h]], axis=0) - np.cross(omega_v, d)
            d, d_dot = sole.T @ d, sole.T @ d_dot
            rates.append(sign * (d[2] * d_dot[0] - d[0] * d_dot[2]) / (d[0] ** 2 + d[2] ** 2))
        return angles, np.array([pitch_rate, roll_rate, rates[0], rates[1]])

    def __call__(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(angles, rates) of the named passive joints, in the order given, rad and rad/s."""
        per_leg = [self.leg_estimates(data, i) for i in range(len(C.LEGS))]
        angles = np.array([per_leg[leg][0][k] for leg, k in zip(self._legs, self._which)])
        rates = np.array([per_leg[leg][1][k] for leg, k in zip(self._legs, self._which)])
        return angles, rates
