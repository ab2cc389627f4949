"""A trained policy as an ONNX file for deployment: `footforge export POLICY_DIR`.

The graph computes what `footforge.rl.policy_files.load_policy(policy_dir, deterministic=True)` computes,
operation for operation, so that onnxruntime and JAX agree to float32 rounding:

    obs (float32 [batch, obs_size], the environment's observation, already clipped to
         +-ObservationConfig.clip as the environment does)
      -> (obs - mean) / std            Brax's running_statistics.normalize, no clip (PPO passes
                                       no max_abs_value); left out if the policy was trained
                                       without normalize_observations
      -> [MatMul, Add, activation] per hidden layer (footforge.rl.networks.network_factory: ELU)
      -> MatMul, Add                   the Gaussian's mean
    actions (float32 [batch, 12])

The action is the mode of Brax's distribution. footforge trains with distribution_type
"normal" (NormalDistribution with the identity postprocessor), whose mode is the network's
mean output itself: no tanh. The learnt standard deviation (std_logparam) only matters for
sampling and is not exported. The output is not clipped: the environment clips it to
+-EnvConfig.action_clip before turning it into PD targets, and so must the robot
(metadata "action").

Everything a controller needs beside the network goes into the model's metadata_props, each a
JSON string: METADATA_KEYS lists them.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from footforge.errors import InputError

OPSET = 17
IR_VERSION = 8
"""ONNX IR version of opset 17: readable by onnxruntime >= 1.12 and most deployment runtimes."""


def default_file(policy_dir: Path) -> Path:
    """Where export writes without --out: in the current folder, never into the policy's own (a
    shipped, tracked policy folder, or a checkpoint whose manifest lists its files), named after
    the run: `flat_aof_B.onnx` for runs/flat_aof_B or its policy/, `flat_aof_B_step3870720.onnx`
    for one of its checkpoints, else the folder's own name."""
    policy_dir = Path(policy_dir).resolve()
    if policy_dir.parent.name == "checkpoints" and policy_dir.name.isdigit():
        return Path(f"{policy_dir.parent.parent.name}_step{int(policy_dir.name)}.onnx")
    return Path(f"{policy_dir.parent.name if policy_dir.name == 'policy' else policy_dir.name}.onnx")


ACTIVATIONS = ("elu", "swish", "silu", "relu", "tanh")
"""Brax activation names (ppo_network_config.json) the exporter translates."""

METADATA_KEYS = (
    "footforge_version",
    "task",
    "feet",
    "policy_type",
    "global_step",
    "joint_names",
    "default_joint_angles_rad",
    "action",
    "pd_gains",
    "control_period_s",
    "sim_dt_s",
    "decimation",
    "observation",
    "network",
)


def export(policy_dir: Path, out: Path | None = None, *, force: bool = False) -> Path:
    """Writes `policy_dir`'s policy as ONNX to `out` (default: default_file, in the current folder), whole or
    not at all. Returns the path written. An existing `out` is replaced only where footforge wrote
    it (an ONNX model whose producer is footforge) or with `force`.

    Raises:
      InputError: the folder is missing or holds no footforge policy, its checkpoint cannot be
        read or its network is of a kind this exporter does not translate, or `out` cannot be
        written, or is a file footforge did not write (without `force`).
    """
    import onnx

    from footforge.atomic import atomic_file
    from footforge.outputs import check_output_file
    from footforge.rl.policy_files import policy_folder

    policy_dir = policy_folder(policy_dir)  # a run's folder: its policy/ (or its newest intact checkpoint)
    if not policy_dir.is_dir():
        raise InputError(
            "no such folder",
            file=str(policy_dir),
            fix="pass a training run's folder (footforge train), or its policy/ folder",
        )
    out = Path(out) if out is not None else default_file(policy_dir)
    check_output_file(out)
    if out.suffix.lower() != ".onnx":
        raise InputError(
            "export writes an ONNX model: --out must end in .onnx",
            file=str(out),
            fix=f"e.g. --out {out.with_suffix('.onnx')}",
        )
    if out.exists() and not force and not _written_by_footforge(out):
        raise InputError(
            "exists and is not an ONNX policy footforge wrote; footforge does not replace it",
            file=str(out),
            fix="give another --out, or pass --force to replace it",
        )
    model = build_model(policy_dir)
    try:
        with atomic_file(out) as tmp:
            onnx.save_model(model, str(tmp))
    except OSError as e:
        raise InputError(
            f"cannot be written: {e.strerror or e}", file=str(out), fix="choose a writable --out path"
        ) from None
    return out


def _written_by_footforge(path: Path) -> bool:
    """Whether `path` is an ONNX model footforge exported (its producer_name)."""
    import onnx

    try:
        return onnx.load(str(path), load_external_data=False).producer_name == "footforge"
    except Exception:  # not ONNX at all (a text file, an image): not ours
        return False


def build_model(policy_dir: Path):
    """The onnx.ModelProto of a policy folder (see the module's docstring)."""
    import onnx

    from footforge.rl.policy_files import load_policy_parameters

    policy = load_policy_parameters(policy_dir)
    kwargs = policy.network_config["network_factory_kwargs"]
    _check_supported(policy_dir, kwargs)
    normalizer, policy_params = policy.params[0], policy.params[1]["params"]
    obs_key = kwargs.get("policy_obs_key", "state")
    mean, std = normalizer.mean, normalizer.std
    if isinstance(mean, dict):  # a privileged critic: the policy reads only its own slice
        mean, std = mean[obs_key], std[obs_key]
    mean, std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
    layers = [policy_params["MLP_0"][f"hidden_{i}"] for i in range(len(policy_params["MLP_0"]))]
    layers.append(policy_params["Dense_0"])
    graph = policy_graph(
        mean if policy.ppo.normalize_observations else None,
        std if policy.ppo.normalize_observations else None,
        [(np.asarray(w["kernel"], np.float32), np.asarray(w["bias"], np.float32)) for w in layers],
        kwargs["activation"],
    )
    model = onnx.helper.make_model(
        graph,
        opset_imports=[onnx.helper.make_opsetid("", OPSET)],
        producer_name="footforge",
        producer_version=_version(),
        doc_string=f"footforge policy {policy_dir.resolve().name}: deterministic action "
        "(the policy mean, unclipped) of the raw observation",
    )
    model.ir_version = IR_VERSION
    onnx.helper.set_model_props(model, metadata(policy.env, policy.ppo, mean.shape[0], policy.global_step, kwargs))
    onnx.checker.check_model(model, full_check=True)
    return model


def _check_supported(policy_dir: Path, kwargs: dict) -> None:
    """The network shapes footforge.rl.networks.network_factory makes; anything else is refused rather
    than exported wrongly."""
    problems = []
    if kwargs.get("distribution_type") != "normal":
        problems.append(f"distribution_type {kwargs.get('distribution_type')!r} (exported: 'normal')")
    if kwargs.get("activation") not in ACTIVATIONS:
        problems.append(f"activation {kwargs.get('activation')!r} (exported: {', '.join(ACTIVATIONS)})")
    if kwargs.get("mean_clip_scale") is not None:
        problems.append("mean_clip_scale")
    if kwargs.get("state_dependent_std"):
        problems.append("state_dependent_std")
    if problems:
        raise InputError(
            f"the policy's network has {'; '.join(problems)}, which the ONNX exporter does not translate",
            file=str(policy_dir / "ppo_network_config.json"),
            fix="export policies trained by this footforge's train_flat.py or train_rough.py",
        )


def policy_graph(
    mean: np.ndarray | None, std: np.ndarray | None, layers: list[tuple[np.ndarray, np.ndarray]], activation: str
):
    """The ONNX graph obs -> actions: optional normalisation, then `layers` (kernel (in, out),
    bias (out,)) with `activation` after every layer but the last."""
    from onnx import TensorProto, helper, numpy_helper

    obs_size, action_size = layers[0][0].shape[0], layers[-1][0].shape[1]
    nodes, initializers = [], []
    x = "obs"
    if mean is not None:
        initializers += [numpy_helper.from_array(mean, "obs_mean"), numpy_helper.from_array(std, "obs_std")]  # type: ignore[arg-type]  # with mean
        nodes += [
            helper.make_node("Sub", [x, "obs_mean"], ["obs_centred"], name="normalise_sub"),
            helper.make_node("Div", ["obs_centred", "obs_std"], ["obs_normalised"], name="normalise_div"),
        ]
        x = "obs_normalised"
    for i, (kernel, bias) in enumerate(layers):
        last = i == len(layers) - 1
        prefix = "mean" if last else f"hidden_{i}"
        initializers += [
            numpy_helper.from_array(kernel, f"{prefix}_kernel"),
            numpy_helper.from_array(bias, f"{prefix}_bias"),
        ]
        nodes.append(helper.make_node("MatMul", [x, f"{prefix}_kernel"], [f"{prefix}_matmul"], name=f"{prefix}_matmul"))
        y = "actions" if last else f"{prefix}_linear"
        nodes.append(helper.make_node("Add", [f"{prefix}_matmul", f"{prefix}_bias"], [y], name=f"{prefix}_add"))
        if not last:
            x = f"{prefix}_out"
            nodes += _activation(activation, y, x, prefix)
    return helper.make_graph(
        nodes,
        "footforge_policy",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", obs_size])],
        [helper.make_tensor_value_info("actions", TensorProto.FLOAT, ["batch", action_size])],
        initializer=initializers,
    )


def _activation(name: str, x: str, y: str, prefix: str) -> list:
    from onnx import helper

    if name == "elu":  # flax's elu: x if x > 0 else alpha (exp(x) - 1), alpha 1
        return [helper.make_node("Elu", [x], [y], alpha=1.0, name=f"{prefix}_elu")]
    if name in ("swish", "silu"):  # x sigmoid(x)
        return [
            helper.make_node("Sigmoid", [x], [f"{prefix}_sigmoid"], name=f"{prefix}_sigmoid"),
            helper.make_node("Mul", [x, f"{prefix}_sigmoid"], [y], name=f"{prefix}_swish"),
        ]
    if name == "relu":
        return [helper.make_node("Relu", [x], [y], name=f"{prefix}_relu")]
    return [helper.make_node("Tanh", [x], [y], name=f"{prefix}_tanh")]


def metadata(env, ppo, observation_size: int, global_step: int, network_kwargs: dict) -> dict[str, str]:
    """metadata_props of the exported model: METADATA_KEYS, each value a JSON string."""
    from footforge import constants as C
    from footforge.envs import observation_layout

    n_passive = observation_layout.passive_joints_of(env, observation_size)
    slices, start = [], 0
    for name, width in observation_layout.layout(env, n_passive):
        slices.append(
            {
                "name": name,
                "start": start,
                "size": width,
                "scale": observation_layout.scale(env, name),
                "description": observation_layout.description(env, name),
            }
        )
        start += width
    if start != observation_size:
        raise InputError(
            f"the policy reads {observation_size} observations but its configuration lays out {start}",
            fix="export with the footforge version that trained the policy",
        )
    o = env.observations
    if env.action == "velocity":
        action_rule = (
            "target_t = clip(target_{t-1} + scale * clip(a, -clip, clip) * control_period_s, joint range); "
            "target_0 = the joint angles at the start"
        )
    else:
        action_rule = "target = clip(default_joint_angles_rad + scale * clip(a, -clip, clip), joint range)"
    data = {
        "footforge_version": _version(),
        "task": env.task,
        "feet": env.feet,
        "policy_type": env.policy,
        "global_step": global_step,
        "joint_names": list(C.ACTUATED_JOINTS),
        "default_joint_angles_rad": [C.DEFAULT_JOINT_ANGLES_RAD[j] for j in C.ACTUATED_JOINTS],
        "action": {
            "model": env.action,
            "scale": env.action_scale,
            "scale_unit": "rad/s per unit action" if env.action == "velocity" else "rad per unit action",
            "clip": env.action_clip,
            "pd_target": action_rule,
            "output": "the policy's mean, unclipped, in joint_names order",
        },
        "pd_gains": {
            "kp_nm_per_rad": C.KP_NM_PER_RAD,
            "kd_nms_per_rad": C.KD_NMS_PER_RAD,
            "effort_limit_nm": C.EFFORT_LIMIT_NM,
            "velocity_limit_rad_s": C.VELOCITY_LIMIT_RAD_S,
            "rate": "applied every sim_dt_s",
        },
        "control_period_s": env.policy_dt,
        "sim_dt_s": env.sim_dt,
        "decimation": env.decimation,
        "observation": {
            "size": observation_size,
            "clip": o.clip,
            "layout": slices,
            "passive_foot_joints": n_passive,
            "normalisation": "inside the graph (Brax running statistics); feed the raw observation, clipped to +-clip",
            "noise_in_training": o.noise,
            **(
                {
                    "height_scan": {
                        "x_m": list(env.height_scan.x_m),
                        "y_m": list(env.height_scan.y_m),
                        "offset_m": o.height_offset_m,
                        "clip_m": o.height_clip_m,
                        "order": "x-major",
                    }
                }
                if env.perceptive
                else {}
            ),
        },
        "network": {
            "policy_hidden_layers": list(ppo.policy_hidden_layers),
            "activation": network_kwargs["activation"],
            "normalize_observations": ppo.normalize_observations,
            "distribution": "normal (mode = mean)",
        },
    }
    assert tuple(data) == METADATA_KEYS
    return {k: json.dumps(v) for k, v in data.items()}


def _version() -> str:
    import footforge

    return footforge.__version__
