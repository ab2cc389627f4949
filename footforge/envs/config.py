"""Configuration of the locomotion environments: frozen dataclasses, one docstring per field.

Defaults are the paper's (Scaldaferri et al. 2024) and, where it is silent, its public baseline's:
OmniIsaacGymEnvs' Anymal and AnymalTerrain tasks (tasks/anymal.py, anymal_terrain.py and their
cfg/task YAML). PPO hyperparameters live apart, in footforge.rl.config (PPOConfig).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Literal

from footforge import constants as C
from footforge.envs import observations, rewards
from footforge.envs.terms import NOT_SAVED, ObservationTerm, RewardTerm  # noqa: F401 (re-exported)
from footforge.envs.terrain import TerrainConfig
from footforge.errors import InputError
from footforge.variants import HAPTIC, PERCEPTIVE, Feet, PolicyType, foot_variant

ContactModel = Literal["stance", "fast", "build"]
"""EnvConfig.contact_model's choices, the default first."""
MjxImpl = Literal["jax", "warp"]
N_ACTUATED = len(C.ACTUATED_JOINTS)


@dataclass(frozen=True)
class CommandConfig:
    lin_vel_x_range: tuple[float, float] = (-2.0, 2.0)
    """Forward velocity command at reset, m/s (flat baseline)."""
    lin_vel_y_range: tuple[float, float] = (-1.0, 1.0)
    """Lateral velocity command, m/s."""
    heading_range: tuple[float, float] = (-3.141592653589793, 3.141592653589793)
    """Target heading at reset, rad; the yaw-rate command follows it."""
    heading_gain: float = 0.5
    """Yaw-rate command = clip(gain * heading error, yaw_rate_limit), 1/s."""
    yaw_rate_limit: float = 1.0
    """rad/s."""
    zero_below: float = 0.0
    """Planar commands slower than this (m/s) are set to zero (the rough baseline uses 0.25)."""
    resample_s: float = 10.0
    """Commands are redrawn this often within an episode, s."""
    standing_fraction: float = 0.0
    """Share of drawn commands that are standing commands: zero planar velocity and zero yaw rate
    (the heading is not steered to). Isaac Lab's velocity tasks draw 2 % (rel_standing_envs 0.02);
    the paper's baselines none, so off by default: a lever for policies that stay up when a command
    changes or stops (the flat issue's measurements say which share helps)."""


@dataclass(frozen=True)
class RewardConfig:
    """The paper's ten terms and two of legged_gym's, each declared once, on one line: its function
    (envs.rewards), scale and own parameters (a RewardTerm). Each term is multiplied by its scale
    and the policy step dt; the sum, the `reward/<name>` metrics, config.json and the overrides
    follow these fields, so a new term is its function and its line here."""

    lin_vel_xy: RewardTerm = RewardTerm(rewards.lin_vel_xy, 1.0, sigma=0.25)
    """exp(-|v_xy,cmd - v_xy|^2 / sigma), sigma (m/s)^2 the kernel's width (runs saved with one
    `tracking_sigma` for both tracking terms load it into both: upgrade_saved)."""
    yaw_rate: RewardTerm = RewardTerm(rewards.yaw_rate, 0.5, sigma=0.25)
    """exp(-(w_z,cmd - w_z)^2 / sigma), sigma (rad/s)^2."""
    lin_vel_z: RewardTerm = RewardTerm(rewards.lin_vel_z, -4.0)
    """v_z^2, (m/s)^2."""
    ang_vel_xy: RewardTerm = RewardTerm(rewards.ang_vel_xy, -0.05)
    """Roll and pitch rate, |w_xy|^2, (rad/s)^2."""
    orientation: RewardTerm = RewardTerm(rewards.orientation, -1.0)
    """|projected gravity_xy|^2 (unpublished value; the paper turns the term on)."""
    base_height: RewardTerm = RewardTerm(rewards.base_height, -10.0, target_m=0.52)
    """(h - target_m)^2, m^2, with h the base height over the ground (unpublished value)."""
    torques: RewardTerm = RewardTerm(rewards.torques, -2e-5)
    """sum tau^2, (N m)^2."""
    joint_acc: RewardTerm = RewardTerm(rewards.joint_acc, -5e-4)
    """sum (qd - qd_prev)^2 of the actuated joints over a policy step, (rad/s)^2 (as the baseline)."""
    action_rate: RewardTerm = RewardTerm(rewards.action_rate, -0.01)
    """sum (a - a_prev)^2."""
    hip: RewardTerm = RewardTerm(rewards.hip, -0.06)
    """sum |q_HAA - default|, rad."""
    feet_air_time: RewardTerm = RewardTerm(rewards.feet_air_time, 0.0, target_s=0.5)
    """sum over touchdowns of (air time - target_s), s, under a moving command: it
    pays for steps long enough to lift every foot. Not among the paper's terms, so off (0) here and
    on the rough task; the flat task sets legged_gym's 1.0 (envs.FLAT_FEET_AIR_TIME; Playground's
    Go1 uses 0.8): without it a flat policy walked on three legs (docs/defaults.md). target_s: the
    air time a step must last to pay, s (legged_gym's 0.5)."""
    stand_still: RewardTerm = RewardTerm(rewards.stand_still, 0.0)
    """sum |q - default| over the actuated joints, rad, under a planar command below 0.1 m/s
    (legged_gym's stand_still term, off there too by default). Not among the paper's terms, so off:
    a lever, with CommandConfig.standing_fraction, for policies that hold still when told to."""
    clip_total_at_zero: bool = True
    """The baseline clips the summed reward at zero from below."""
    fall: float = -1.0
    """Added once, after the clip and not multiplied by dt, on the step where an episode ends by a
    fall (base or knee contact, or a diverged simulation), not by a time-out. The paper penalises
    falls without a value; OmniIsaacGymEnvs' flat Anymal adds -1 after its clip (its rough task's
    -1 x dt comes before the clip, which erases it), so footforge follows the flat task in both."""

    def with_scales(self, **scales: float) -> RewardConfig:
        """This configuration with the named terms' scales replaced."""
        return replace(self, **{name: replace(getattr(self, name), scale=s) for name, s in scales.items()})


@dataclass(frozen=True)
class ObservationConfig:
    """The observation's groups, each declared once, in the order of the observation vector."""

    base_lin_vel: ObservationTerm = ObservationTerm(observations.base_lin_vel, 3, scale=2.0, noise=0.1)
    """Base linear velocity in the base frame, m/s."""
    base_ang_vel: ObservationTerm = ObservationTerm(observations.base_ang_vel, 3, scale=0.25, noise=0.2)
    """Base angular velocity in the base frame, rad/s."""
    projected_gravity: ObservationTerm = ObservationTerm(observations.projected_gravity, 3, noise=0.05)
    """Unit gravity direction in the base frame."""
    command: ObservationTerm = ObservationTerm(observations.command, 3, scale=(2.0, 2.0, 0.25))
    """vx, vy (m/s), yaw rate (rad/s)."""
    joint_pos: ObservationTerm = ObservationTerm(observations.joint_pos, N_ACTUATED, noise=0.01)
    """Actuated joint angles minus the defaults, rad."""
    joint_vel: ObservationTerm = ObservationTerm(observations.joint_vel, N_ACTUATED, scale=0.05, noise=1.5)
    """Actuated joint velocities, rad/s."""
    last_action: ObservationTerm = ObservationTerm(observations.last_action, N_ACTUATED)
    """The previous policy output."""
    pd_target: ObservationTerm = ObservationTerm(observations.pd_target, N_ACTUATED, read_by="pd_targets")
    """With pd_targets (for velocity actions): the actuated joints' PD targets minus
    the defaults, rad, noiseless (the controller knows them)."""
    height_scan: ObservationTerm = ObservationTerm(
        observations.height_scan, "scan_points", read_by="perceptive", scale=5.0, noise=0.06
    )
    """P/PH only: clip(base z - height_offset_m - terrain height, +-height_clip_m) at the scan
    points, m, x-major (EnvConfig.height_scan)."""
    foot_joint_pos: ObservationTerm = ObservationTerm(
        observations.foot_joint_pos, "passive_joints", read_by="haptic", noise=0.01
    )
    """BH/PH only: passive foot joint angles, rad."""
    foot_joint_vel: ObservationTerm = ObservationTerm(
        observations.foot_joint_vel, "passive_joints", read_by="haptic", scale=0.05, noise=1.5
    )
    """BH/PH only: passive foot joint velocities, rad/s."""
    height_offset_m: float = 0.5
    """The height scan reads the terrain this far below the base, m."""
    height_clip_m: float = 1.0
    """The height scan's values are clipped to +-this, m (before the scale)."""
    pd_targets: bool = False
    """Observe the actuated joints' PD targets (pd_target); off by default, and in configurations
    saved before it existed (whose networks do not read it). Turn it on with velocity actions
    (EnvConfig.action), whose target is the integral of every past action: neither q nor the last
    action reveals it, and at ANYmal C's kp 80 N m/rad q lags it by torque / kp, up to 1 rad, so a
    policy without it is partly blind to its own torques (OmniIsaacGymEnvs' flat Anymal needs no
    such input: its far stiffer drive holds q at the target). Position actions observe the target
    already (default + scale x last action). With it a CPU run learned to survive its episodes
    sooner (docs/defaults.md)."""
    noise: bool = True
    """Add the uniform noise (off for evaluation of the noiseless state)."""
    clip: float = 5.0
    """The whole observation is clipped to +-clip after scaling."""


@dataclass(frozen=True)
class ResetConfig:
    """The joint state an episode starts from (OmniIsaacGymEnvs' reset_idx): the default angles
    times a factor drawn per joint, and small random joint velocities. Base pose and velocity are
    not randomised (the baselines spawn the base at rest)."""

    joint_pos_factor_range: tuple[float, float] = (0.5, 1.5)
    """Each actuated joint starts at default x U(lo, hi) (the rough baseline's (0.5, 1.5); its flat
    task starts at the defaults, (1, 1)), clipped to the joint range."""
    joint_vel_max: float = 0.1
    """Each actuated joint starts with a velocity drawn in [-max, max], rad/s (both baselines)."""


@dataclass(frozen=True)
class RandomizationConfig:
    """Domain randomisation, drawn once per robot (per environment slot) when training starts, as
    legged_gym draws it when it creates its environments. Each is off where its range is None.
    Defaults: all off, as the paper's baseline (OmniIsaacGymEnvs' Anymal and AnymalTerrain: ground
    friction 1.0 static and dynamic, no randomisation) and the paper itself; the ranges to switch
    on are legged_gym's."""

    friction_range: tuple[float, float] | None = None
    """Sliding friction coefficient of every contact of the robot with the ground, dimensionless;
    legged_gym's is (0.5, 1.25), on by default there. Two differences to weigh before using it:
    legged_gym draws the robot's coefficient and PhysX averages it with the terrain's 1.0 (so its
    contacts see 0.75-1.125), while this sets the contact's coefficient itself (MuJoCo combines two
    geoms' by their maximum; the models' ground is 1.0, the robot's 0.8); and MuJoCo's pyramidal
    cone (contact_model 'stance', 'fast') bounds a diagonal sideways force to mu / sqrt(2) of the
    normal force, against the 0.49 that ANYmal C's default stance needs (EnvConfig.contact_model):
    below mu of about 0.7 a robot holding still slides (docs/defaults.md)."""
    payload_mass_kg_range: tuple[float, float] | None = None
    """Mass added to the base at its centre of mass, kg; legged_gym's added_mass_range is (-1, 1),
    off by default there. The base's inertia scales with its mass."""
    motor_strength_range: tuple[float, float] | None = None
    """Factor on every actuator's PD gains and torque limit; (0.9, 1.1) is the usual range of
    legged_gym's successors (legged_gym itself has none)."""

    @property
    def enabled(self) -> bool:
        return any(r is not None for r in (self.friction_range, self.payload_mass_kg_range, self.motor_strength_range))


@dataclass(frozen=True)
class PushConfig:
    interval_s: float = 15.0
    """Every this many seconds the base's planar velocity is set at random, s."""
    max_speed: float = 1.0
    """|v_x|, |v_y| drawn in [-max, max], m/s."""
    enabled: bool = True


@dataclass(frozen=True)
class HeightScanConfig:
    """The robot-centric height map of the perceptive policies: a grid turning with the base's yaw."""

    x_m: tuple[float, ...] = (-0.8, -0.7, -0.6, -0.5, -0.4, -0.3, -0.2, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)
    """Forward offsets of the points from the base, m (the paper's 14)."""
    y_m: tuple[float, ...] = (-0.5, -0.4, -0.3, -0.2, -0.1, 0.1, 0.2, 0.3, 0.4, 0.5)
    """Lateral offsets, m (the paper's 10)."""

    @property
    def num_points(self) -> int:
        return len(self.x_m) * len(self.y_m)


@dataclass(frozen=True)
class CurriculumConfig:
    """The game-inspired curriculum: each robot owns a terrain level and a column."""

    initial_max_level: int = 5
    """Robots start on a level drawn from 0..initial_max_level (legged_gym's max_init_terrain_level)."""
    initial_level_shares: tuple[float, ...] | None = None
    """Instead, the share of robots starting on each level (one per level, normalised). A resumed rough run
    sets it in its environment from the level shares its curve last logged (footforge.rl.train's
    logged_level_shares), so the curriculum goes on where it stood rather than back to 0..initial_max_level: a
    departure from legged_gym, which trains in one call and keeps no levels across a restart, for training
    that a 2-core CPU does in many calls. Not written to config.json: a run's configuration stays the one
    it began with."""
    initial_level_shares_by_kind: tuple[tuple[float, ...], ...] | None = None
    """Or, for each terrain kind (footforge.envs.terrain.KINDS order), the share of robots on each level
    (rows normalised one by one): a robot's first level is drawn from the row of its column's kind, and from
    the rule above where that row is all zero. A resumed rough run sets it from the steps its episodes spent
    on each kind and level, recorded with its checkpoint (footforge.rl.train's checkpoint_level_shares_by_kind),
    so that each kind's robots start on that kind's own levels (stairs low, smooth slopes high) rather than
    every kind on the levels of all kinds together. Not written to config.json, as initial_level_shares."""
    promote_fraction_of_tile: float = 0.5
    """Promoted when the episode took it farther than this fraction of a tile from its spawn."""
    demote_fraction_of_command: float = 0.25
    """Demoted when it covered less than this fraction of |v_cmd| x episode length."""
    spawn_radius_m: float = 0.5
    """Spawns are drawn uniformly within this distance of the tile centre (on the platform), m."""


@dataclass(frozen=True)
class EnvConfig:
    task: Literal["flat", "rough"] = "flat"
    """flat: a plane; rough: the terrain heightfield with the curriculum."""
    feet: Feet = "aof"
    """Foot variant; the model is `footforge build --variant <feet>`'s scene.xml."""
    policy: PolicyType = "B"
    """B blind; P perceptive (height scan, rough task); BH, PH: + haptic (passive foot joint
    positions and velocities)."""
    build_dir: str | None = None
    """Folder of the build outputs; default build/<feet> (anymal.DEFAULT_BUILD_ROOT). Environments
    never build: a missing build is an input error that names the command making it (the
    pipelines build the default folders first: footforge.cli.builds)."""
    sim_dt: float = 0.0025
    """Physics step, s (MuJoCo clamps contact time constants to at least 2 steps). The default is
    contact_model 'stance''s; envs.default_config and envs.with_contact_model set the step each
    contact model needs on each feet (its row in envs.contact_physics)."""
    decimation: int = 8
    """Physics steps per policy step (50 Hz)."""
    episode_length_s: float = 20.0
    """Time-outs end an episode as a truncation (PPO bootstraps them)."""
    diverged_speed: float = 1000.0
    """Generalised velocity (m/s for the base's translation, rad/s otherwise) above which a
    robot's physics counts as diverged, as a NaN does: its episode ends as a fall with zero
    metrics. Far above anything a walking or falling ANYmal does; it catches diverged states that
    stay finite, which a NaN check alone lets through (docs/defaults.md)."""
    action: Literal["velocity", "position"] = "position"
    """How the 12 policy outputs a (clipped to +-action_clip) become the PD targets (rad), kept
    within the joint ranges. Both tasks use position actions (envs.default_config). The flat
    baseline's velocity actions stay an option: on ANYmal C's soft drive (kp 80 N m/rad, kd 2)
    their integral turns exploration noise into a random walk of the targets, and PPO learned to
    stand, not walk, with them (48 M steps on an H100), where position actions walked within
    1.5 M CPU steps (fixed 0.6 m/s command) and 11 M GPU steps (full commands):
    benchmarks/RESULTS.md#learning.

    - velocity (flat task): joint velocities integrated onto the previous *target*,
      target_t = target_t-1 + action_scale x a x policy_dt, with target_0 the joint angles the
      episode starts at. This is OmniIsaacGymEnvs' flat Anymal (`current_targets += 13.5 a dt`
      with rl_games' actions clipped to [-1, 1]). The paper says the velocities are "integrated
      with the current joint positions"; read literally (target = q + 13.5 a dt) a zero action
      lets the PD target follow the sagging joints and the robot collapses in 0.4 s, so the
      baseline's form, under which a zero action holds the pose, is the one followed.
    - position (rough task): target = default + action_scale x a (OmniIsaacGymEnvs'
      AnymalTerrain and legged_gym)."""
    action_scale: float = 0.5
    """rad per unit action under position actions (the default: OmniIsaacGymEnvs' AnymalTerrain and
    legged_gym's 0.5), rad/s per unit under velocity actions (the flat baseline's 13.5,
    envs.stability.VELOCITY_ACTION_SCALE). Until 2026-11-28 the default was 13.5, so EnvConfig()
    alone paired position actions with 13.5 rad per unit; saved configs carry their own."""
    action_clip: float = 1.0
    """Policy outputs are clipped to +-this before they are used (rewards and the last-action
    observation see the clipped value): rl_games clips to the baselines' action space [-1, 1]."""
    solver_iterations: int = 8
    """MJX Newton iterations per step (Playground uses 1-4); at least what contact_model needs on
    the feet in the precision (envs.contact_physics: stance ball 8, AFF 16, AOF 8 in float32, AFF and
    AOF 16 under float64_physics; envs.default_config, envs.with_contact_model and
    envs.with_float64_physics set it), refused with fewer."""
    solver_ls_iterations: int = 16
    """MJX line-search iterations per Newton iteration (stance: 16 on every feet)."""
    contact_model: ContactModel = "stance"
    """The MJX contact model; its settings per feet, precision and ground are one table,
    envs.contact_physics.CONTACT_PHYSICS (limits checked by envs.anymal.check_contact_model;
    envs.with_contact_model sets the step and solver iterations each needs). Default "stance".

    Why: with kp 80 N m/rad ANYmal C stands on static friction (each foot pushes sideways with
    about half its load); MuJoCo's friction is regularised, so a robot holding still creeps
    towards a crouch, where PhysX, the baselines' engine, holds. A robot that cannot stand still
    corrupts the base-height and slippage indices that compare the feet.

    - stance (default): pyramidal cone, impratio 10, solimp 0.99/0.999/0.001 (0.97/0.995 in
      float32 for the adaptive feet and on heightfields; the adaptive feet's soles also on a
      softer normal, solref (-1e4, -400): envs.contact_physics), semi-implicit
      Euler, 2.5 ms x 8 per policy step, Newton / line-search iterations ball 8/16, AFF 16/16,
      AOF 8/16 (AFF and AOF 16/16 under float64_physics). Zero-action robots sink and slide a few
      millimetres in 10 s, flat and on rough level 0, float32 and float64. Needs a friction
      coefficient of about 0.7 or more. Costs 1.4-3.4x fast per step on the CPU.
    - fast: MuJoCo's defaults (pyramidal, impratio 1, solimp 0.9/0.95, implicitfast), 4 / 8
      iterations, the baselines' 5 ms x 4, as MuJoCo Playground trains: stable and cheap, but a
      robot at rest sinks and slides 150-180 mm in 10 s. The walking policies so far trained on it.
    - build: the built scene's elliptic contact, converged (16 / 50 iterations, 2.5 ms): holds a
      stance but diverges AOF under an untrained policy, at 5-10x fast's cost.

    Measurements (sinking and slip per feet, costs, friction limits):
    benchmarks/RESULTS.md#stance-physics."""
    float64_physics: bool = False
    """Step MJX in float64 (JAX's x64 mode; MJX's own default is float32). x64 is a switch of the
    whole process, set before JAX makes its first array by
    footforge.envs.enable_float64_physics(config) (training, `--float64-physics`, and evaluation
    call it; in one's own script call it first, or set JAX_ENABLE_X64=1); an environment built
    without it refuses to start. The policy's side stays float32: the environment and the
    training wrapper hand observations, rewards, metrics and info over in float32
    (envs.wrappers.policy_side), and the networks' parameters are made float32
    (train.network_factory). Under contact_model 'stance' float64 holds the adaptive feet at the
    stiffer impedance and the build's solref, about twice as still as float32 (contact_model)."""
    mjx_impl: MjxImpl = "jax"
    """MJX's backend (mujoco.mjx.put_model's impl): "jax", MJX in JAX on any device (the default;
    every MJX figure in benchmarks/RESULTS.md uses it); "warp", MuJoCo Warp's kernels, NVIDIA GPUs
    only, with mujoco-mjx's `warp` extra installed (warp-lang, mujoco_warp). Refused with a clear error
    where it cannot run (envs.anymal.check_mjx_impl); not yet measured on a GPU."""
    physics: Literal["mjx", "mujoco"] = "mjx"
    """The engine that steps the robots (footforge.envs.engine): "mjx", MuJoCo MJX in JAX (a GPU's
    engine; the library default, and what every run saved before 2026-11-28 used), or "mujoco",
    MuJoCo's C engine in float64, threaded, reached from the jitted step by a host callback: 3-28x
    MJX's speed on a CPU. The same model, settings and task code either way; `--physics auto` (the
    commands' default) takes mujoco on a CPU and mjx elsewhere. A run's checkpoints resume and its
    policies evaluate under either engine."""
    commands: CommandConfig = field(default_factory=CommandConfig)
    rewards: RewardConfig = field(default_factory=RewardConfig)
    observations: ObservationConfig = field(default_factory=ObservationConfig)
    pushes: PushConfig = field(default_factory=PushConfig)
    reset: ResetConfig = field(default_factory=ResetConfig)
    randomization: RandomizationConfig = field(default_factory=RandomizationConfig)
    privileged_critic: bool = False
    """Asymmetric actor-critic: the value network also reads privileged observations (true base
    velocity, foot contact forces, terrain heights around the base, ground friction) that the
    policy never sees. Off by default, as the paper (a shared observation)."""
    terrain: TerrainConfig = field(default_factory=TerrainConfig)
    """Rough task only."""
    height_scan: HeightScanConfig = field(default_factory=HeightScanConfig)
    curriculum: CurriculumConfig = field(default_factory=CurriculumConfig)
    shank_collisions: bool = True
    """Rough task: the shank tubes collide with the terrain (as capsules of the same radius and
    extent: MJX cannot collide cylinders with heightfields), so shanks stop at stair risers as in
    OmniIsaacGymEnvs, where the whole robot collides. False: feet only (with the geometric base
    and knee probes that end episodes), as MuJoCo Playground's Go1. On MJX the shanks cost about
    half the ball robot's rough-terrain throughput and nothing measurable on AOF
    (docs/defaults.md)."""
    heightfield_soles: Literal["spheres", "box"] = "spheres"
    """Rough task, AFF and AOF: what the sole plates collide through on the terrain heightfield.
    "spheres" (default): each sole box of the build stands in as a grid of spheres on its bottom face
    (heightfield_sole_grid, heightfield_sole_radius_m; the spheres of footforge.geometry.sole_primitives,
    standing where the box stands on flat ground). "box": the build's boxes.

    Why spheres: MuJoCo's C engine collides a box with a heightfield through one contact per terrain
    prism (penetration along a prism's side faces as often as its top: up to 5.1x the plane's force,
    a sole thrown 0.24-0.82 m on a 20 deg slope), MJX through its own four-point manifold, so the two
    engines' rough AOF robots parted by 2.3-6.3 mm of foot within two policy steps; a sphere touches a
    prism's top face at one point in both engines, and with spheres they agree to 4e-6 m
    (benchmarks/box_on_heightfield.py, tests/test_engines.py, RESULTS.md "Physics engines"). What
    it costs: a heightfield feature narrower than the spheres' spacing can reach between them; the
    terrain's 0.1 m samples ramp over a whole cell, and a 3 x 2 grid spaces the spheres 2.3-3.0 cm
    along the foot and 3.9 cm across. The flat task keeps the boxes (on a plane both engines give
    the box's four corners)."""
    heightfield_sole_grid: tuple[int, int] = (3, 2)
    """Spheres per sole plate along the foot (x) and across it (y), heightfield_soles "spheres"."""
    heightfield_sole_radius_m: float = 0.008
    """Their radius, m."""
    terminate_on_knees: int = 2
    """A step with at least this many thigh (knee) contacts ends the episode; any base contact does."""

    @property
    def haptic(self) -> bool:
        """The policy reads the passive foot joints (BH, PH)."""
        return self.policy in HAPTIC

    @property
    def perceptive(self) -> bool:
        """The policy reads the height scan (P, PH)."""
        return self.policy in PERCEPTIVE

    @property
    def policy_dt(self) -> float:
        return self.sim_dt * self.decimation

    @property
    def episode_steps(self) -> int:
        return int(round(self.episode_length_s / self.policy_dt))


def check_policy_on_feet(config: EnvConfig, feet: str, source: str | None = None) -> None:
    """Raises InputError for a haptic policy (BH, PH) on derived feet other than its own: it reads
    the passive joints of the feet it was trained on, which other derived feet do not have. On the
    closed chain (`full`) it reads those joints' estimates from the feet's sensors
    (footforge.rl.foot_imu). Blind and perceptive policies run on any feet (zero-shot). `source`:
    the policy's folder or file, named in the error."""
    if config.haptic and feet != config.feet and not foot_variant(feet).closed_chain:
        raise InputError(
            f"a {config.policy} policy reads the passive joints of the {config.feet} feet it was "
            f"trained on; the {feet} feet have others",
            file=source,
            fix=f"run it on its own {config.feet} feet or the closed chain (full), or a blind (B) "
            "or perceptive (P) policy on other feet",
        )


def check_feet_and_policy(feet: str, policy: str) -> None:
    """Raises InputError for a haptic policy on feet without passive joints."""
    if policy in HAPTIC and not foot_variant(feet).adaptive:
        raise InputError(
            f"policy type {policy} reads the feet's passive joints; the ball foot has none",
            fix="use B with ball feet, or aff/aof feet",
        )


_SAVED_BEFORE_TERMS = {  # ObservationConfig's flat keys before each group was declared once (2026-11-26)
    "lin_vel_scale": ("base_lin_vel", "scale"),
    "lin_vel_noise": ("base_lin_vel", "noise"),
    "ang_vel_scale": ("base_ang_vel", "scale"),
    "ang_vel_noise": ("base_ang_vel", "noise"),
    "gravity_noise": ("projected_gravity", "noise"),
    "command_scale": ("command", "scale"),
    "joint_pos_scale": ("joint_pos", "scale"),
    "joint_pos_noise": ("joint_pos", "noise"),
    "joint_vel_scale": ("joint_vel", "scale"),
    "joint_vel_noise": ("joint_vel", "noise"),
    "foot_joint_pos_scale": ("foot_joint_pos", "scale"),
    "foot_joint_pos_noise": ("foot_joint_pos", "noise"),
    "foot_joint_vel_scale": ("foot_joint_vel", "scale"),
    "foot_joint_vel_noise": ("foot_joint_vel", "noise"),
    "height_scale": ("height_scan", "scale"),
    "height_noise_m": ("height_scan", "noise"),
}

_REWARD_PARAMETERS_BEFORE_TERMS_OWNED_THEM = {  # RewardConfig's flat parameters before each term held its own
    "tracking_sigma": (("lin_vel_xy", "sigma"), ("yaw_rate", "sigma")),
    "base_height_target_m": (("base_height", "target_m"),),
    "feet_air_time_target_s": (("feet_air_time", "target_s"),),
}


def upgrade_saved(env: dict) -> dict:
    """An EnvConfig as a run saved it (config.json's "env"), in today's form: runs saved before the
    observation groups and reward terms were declared once hold flat scale and noise keys
    (lin_vel_scale, ...) and bare reward scales, and runs saved before each reward term held its
    own parameters hold them flat in "rewards" (tracking_sigma, shared by both tracking terms,
    base_height_target_m, feet_air_time_target_s); the values carry over unchanged. Rough runs
    saved before EnvConfig.heightfield_soles collided their soles as boxes, and load so."""
    env = dict(env)
    if env.get("task") == "rough" and "heightfield_soles" not in env:
        env["heightfield_soles"] = "box"  # rough runs saved before the key stood on the build's sole boxes
    if "observations" in env:
        obs: dict[str, Any] = {}
        for key, value in env["observations"].items():
            if key in _SAVED_BEFORE_TERMS:
                group, attribute = _SAVED_BEFORE_TERMS[key]
                obs.setdefault(group, {})[attribute] = value
            else:
                obs[key] = value
        env["observations"] = obs
    if "rewards" in env:
        reward_terms = rewards.terms(RewardConfig())
        saved = {
            key: {"scale": value} if key in reward_terms and not isinstance(value, dict) else value
            for key, value in env["rewards"].items()
        }
        for key, places in _REWARD_PARAMETERS_BEFORE_TERMS_OWNED_THEM.items():
            if key in saved:
                value = saved.pop(key)
                for term, parameter in places:
                    saved[term] = {**saved.get(term, {})}
                    saved[term]["params"] = {**saved[term].get("params", {}), parameter: value}
        env["rewards"] = saved
    return env
