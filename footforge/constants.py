"""Names and published figures of ANYmal C used across footforge (reference: anymal_c.md)."""

from __future__ import annotations

LEGS = ("LF", "RF", "LH", "RH")
LEG_JOINTS = ("HAA", "HFE", "KFE")
ACTUATED_JOINTS = tuple(f"{leg}_{j}" for leg in LEGS for j in LEG_JOINTS)

BASE_BODY = "base"
FLOATING_JOINT = "floating_base"
IMU_FRAME = "imu_link"
FOOT_MOUNT_FRAME = "{leg}_foot_mount"
"""Frame (link) of the robot description where an adaptive foot is bolted."""
FOOT_MODEL_NAME = "{leg}_foot"
"""dm_control namespace of each attached foot: bodies are named e.g. 'LF_foot/front_arch'."""

# PD position control of the paper's rough-terrain baseline (applied at the simulation rate).
KP_NM_PER_RAD = 80.0
KD_NMS_PER_RAD = 2.0
EFFORT_LIMIT_NM = 80.0
VELOCITY_LIMIT_RAD_S = 7.5
"""Joint velocity limit of the actuators, as published (recorded in exported policies)."""

# Default joint angles of the paper's baselines, rad: HAA +left/-right, HFE and KFE front/hind.
DEFAULT_JOINT_ANGLES_RAD = {
    **{f"{leg}_HAA": (0.03 if leg[0] == "L" else -0.03) for leg in LEGS},
    **{f"{leg}_HFE": (0.4 if leg[1] == "F" else -0.4) for leg in LEGS},
    **{f"{leg}_KFE": (-0.8 if leg[1] == "F" else 0.8) for leg in LEGS},
}


BALL_FOOT_RADIUS_M = 0.03
"""ANYmal C's ball foot (the description's ball_radius); its centre is the foot mount."""

BUILD_FORMAT = 3
"""Version of what a build folder holds (build_report.json's "format"), raised whenever a newer
footforge's environments rely on something older builds lack. 2: robot scenes carry the
parameter file's `contact` settings and the `stand` keyframe. 3: the closed chain's joint stops
are as stiff as its loop closures (with MuJoCo's default stops it diverged under walking
policies; a build from a user's own sidecar would otherwise keep them)."""

BUILD_FORMAT_NEEDS = "the closed chain's stiff joint stops, the `stand` keyframe and the parameter file's contacts"
"""What builds older than BUILD_FORMAT lack, in the words of the refusal."""
