"""Named training configurations (presets) and `section.field=value` overrides over them.

A training run's configuration is a preset of its task, applied to the task's defaults for its
feet and policy type (envs.default_config, rl.config.default_ppo), then overrides, in order:

    env, ppo = resolve("flat", "aof", "B", preset="cpu", overrides=["ppo.entropy_cost=0.01"])

An override names a leaf of config.json's form of the configuration (rl.config.to_dict), `env.`
or `ppo.` first: `env.commands.resample_s=10`, `env.rewards.feet_air_time.scale=0`,
`env.rewards.lin_vel_xy.params.sigma=0.5` (a reward term's own parameter),
`ppo.policy_hidden_layers=512,256,128`. Its value is read as the type of the field it sets (a
comma-separated list for a tuple, true/false for a flag, none where the field may be None). This is
the pattern of Isaac Lab's Hydra overrides (`env.rewards.x.weight=...`) and mjlab's tyro CLI, in
the one form config.json already has; the resolved configuration goes through to_dict/from_dict
before a run starts, so what is trained is what the run folder says.

Two fields set more than themselves, as their own flags do: `env.contact_model` brings the physics
step and solver iterations of that contact model on the run's feet (envs.physics, as
`--contact-model`), and `env.float64_physics` the iterations its precision needs
(envs.with_float64_physics). The run-time choices are flags, not overrides: the engine
(`--physics`), the build (`--build-root`), the task, feet and policy type.

A run records its preset and overrides in config.json ("recipe"), and a policy's card lists them:
the configuration is reproducible from the two (tests/test_presets.py checks every shipped policy).
"""

from __future__ import annotations

import difflib
import math
import types
import typing
from dataclasses import dataclass, fields, is_dataclass, replace

from footforge.envs import FLAT_REWARD_SCALES
from footforge.errors import InputError

CPU_SIZE = (
    "ppo.num_envs=128",
    "ppo.unroll_length=24",
    "ppo.batch_size=64",
    "ppo.num_minibatches=4",
    "ppo.num_eval_envs=64",
    "ppo.checkpoint_every_steps=258048",
)
"""A 2-core CPU's batch: 128 robots x 24-step unrolls, 4 minibatches of 64 trajectories (6,144 steps per
iteration, 2-3 s under MuJoCo's C engine), a checkpoint every 42 iterations (258,048 steps, about
2 minutes). The paper's 2048 x 48 is 16x the robots: one iteration there is a minute on this CPU."""

CPU_FLAT_COMMANDS = ("env.commands.lin_vel_x_range=-1,1", "env.commands.lin_vel_y_range=-0.5,0.5")
"""Commands up to 1 m/s forward and 0.5 m/s sideways (legged_gym's ANYmal C flat task: +-1 m/s both;
MuJoCo Playground's Go1: +-1.5 / +-0.8), where the paper's baseline draws +-2 / +-1: every policy
that walked on this CPU so far was trained on these."""


CPU_RECIPE = ("env.contact_model=fast",) + CPU_SIZE + CPU_FLAT_COMMANDS + ("ppo.entropy_cost=0.001",)
"""What every `cpu` preset shares: the `fast` contact, the CPU's batch, the CPU's commands, PPO entropy 0.001."""

CPU_FLAT = CPU_RECIPE + ("env.rewards.feet_air_time.scale=0", "ppo.num_timesteps=10000000")
"""The flat `cpu` preset's overrides, which its second stage `cpu-robust` extends."""


@dataclass(frozen=True)
class Preset:
    """A named training configuration: the task's defaults, a contact model and overrides."""

    name: str
    summary: str
    """One line for --help and the policy card."""
    overrides: tuple[str, ...] = ()
    """`section.field=value` assignments over the task's defaults, applied in order (the module's
    docstring); `env.contact_model` first where a preset changes it."""
    after: str | None = None
    """A second stage: the preset whose walking policy this one goes on from (`--init-from`); None: from
    scratch. `footforge train` says so where a run of it starts from scratch (untried)."""


FLAT_PRESETS = (
    Preset(
        "default",
        "the flat task's defaults: the paper's 2048 robots x 48 steps and 100 M steps, the `stance` "
        "contact, commands +-2 / +-1 m/s every 5 s (a GPU's run)",
    ),
    Preset(
        "cpu",
        "sized for a 2-core CPU under MuJoCo's C engine: 128 robots x 24 steps, 10 M steps, the `fast` "
        "contact, commands +-1 / +-0.5 m/s, no feet-air-time term, PPO entropy 0.001",
        CPU_FLAT,
    ),
    Preset(
        "cpu-robust",
        "the `cpu` preset's second stage, for a policy that walks (--init-from): a push every 5 s and a new "
        "command every 2.5 s (3 pushes and 7 changes of command per 20-s episode, where `cpu` has 1 and 3), "
        "10 M steps",
        CPU_FLAT + ("env.pushes.interval_s=5", "env.commands.resample_s=2.5"),
        after="cpu",
    ),
    Preset(
        "paper",
        "the paper's settings as far as it publishes them (2048 robots x 48 steps, joint-velocity "
        "actions scaled 13.5, its rewards' scales, its PPO baseline's rates), the rest its baseline's "
        "(OmniIsaacGymEnvs' Anymal, legged_gym): commands every 10 s, no feet-air-time term",
        (
            "env.action=velocity",
            "env.action_scale=13.5",
            "env.observations.pd_targets=true",
            "env.rewards.lin_vel_xy.scale=1.0",
            "env.rewards.yaw_rate.scale=0.5",
            "env.rewards.base_height.scale=-10.0",
            "env.rewards.feet_air_time.scale=0",
            "env.commands.resample_s=10",
            "ppo.learning_rate=0.0003",
            "ppo.adaptive_kl=0.008",
            "ppo.entropy_cost=0.001",
            "ppo.policy_output_init_scale=1.0",
        ),
    ),
    Preset(
        "forward",
        "one command, 0.6 m/s straight ahead, no pushes, the `fast` contact, the CPU's batch and 3 M "
        "steps, the task's rewards and PPO otherwise: the quickest check that PPO learns to walk (ball "
        "feet walk after 3 M steps)",
        ("env.contact_model=fast",)
        + CPU_SIZE
        + (
            "env.commands.lin_vel_x_range=0.6,0.6",
            "env.commands.lin_vel_y_range=0,0",
            "env.commands.heading_range=0,0",
            "env.pushes.enabled=false",
            "ppo.num_timesteps=3000000",
        ),
    ),
)
"""The flat task's presets. `cpu-robust`: falls over the paper's 60 s come within 2 s of a push or of a new command
(footforge evaluate's falls_after_push / falls_after_command); a policy that walks under `cpu` is fine-tuned
with three times the pushes and more than twice the changes of command of an episode. The references resample
the command every 10 s (legged_gym's resampling_time, Isaac Lab's resampling_time_range) and push every 15 s
(legged_gym's push_interval_s) for the whole run, from scratch; here the denser schedule is a second stage
from a policy that walks, as the push curriculum that hardened `flat_aof_B` was (from scratch it is untried), and
the evaluation keeps the references' schedule (a command every 10 s, a push every 15 s), so the stage trains
harder than it is tested. Measured on this 2-core CPU (benchmarks/RESULTS.md, "Learning"): `flat_aff_B`
fine-tuned 10 M steps with pushes every 5 s alone lost 30 of 256 robots over 60 s (36 before; those after a
new command 24 to 23); with a new command every 2.5 s as well, 7 (after a new command 6)."""

ROUGH_PRESETS = (
    Preset(
        "default",
        "the rough task's defaults: the paper's 2048 robots x 48 steps, 512-256-128 networks, 200 M "
        "steps, the terrain curriculum (a GPU's run)",
    ),
    Preset(
        "cpu",
        "the flat `cpu` preset's recipe on the rough task: 128 robots x 24 steps, 30 M steps (the rough issue's "
        "target for terrain level 5), the `fast` contact, commands +-1 / +-0.5 m/s, the flat task's reward "
        "scales, PPO entropy 0.001",
        CPU_RECIPE
        + tuple(f"env.rewards.{term}.scale={scale}" for term, scale in FLAT_REWARD_SCALES.items())
        + ("ppo.num_timesteps=30000000",),
    ),
)
"""The rough task's presets. `cpu` is the flat `cpu` preset's recipe (the one that walks on this CPU) on the rough
task, where the task's defaults stay for a GPU's batch:
- PPO entropy 0.001, not the task's 0.01 (legged_gym's): at 0.01 the rough AOF P run (2048 x 48, 135 PPO
  iterations) drove its Gaussian's standard deviation from 1.0 to 3.1 in 13 M steps while its forward error stayed
  at 0.50-0.55 m/s, and on flat ground the same cost kept AOF from walking until it was lowered to 0.001.
- The flat task's reward scales (envs.FLAT_REWARD_SCALES: tracking doubled, lin_vel_z -0.03 not -4, base height
  -2 not -10, joint_acc and action_rate the flat baseline's), the `fast` contact (2.5 ms x 8 -> 5 ms x 4) and
  commands +-1 / +-0.5 m/s. Under the rough baseline's scales (OmniIsaacGymEnvs' AnymalTerrain, the task's
  defaults) and the `stance` contact, entropy 0.001, AOF P stood still for 5.68 M steps (forward error 0.49-0.51
  m/s from 2.8 M on, 99 % of robots on level 0): its penalties summed to about twice its tracking reward, so the
  total, clipped at zero each step as the baseline does, was near zero (0.4 per episode) and gave PPO little to
  follow. With these scales the same run's forward error fell to 0.34 m/s by 1.8 M steps, as flat AOF's does
  under the flat `cpu` preset (0.45 at 1.7 M), at 3,100 policy steps/s against 2,150, and its robots climbed the
  curriculum: mean level 0.9 at 10 M steps, 2.2 at 21.4 M (benchmarks/RESULTS.md, "Learning"). legged_gym's
  rough ANYmal weighs vertical velocity -2 against tracking 1; here -0.03, the flat baseline's, so that climbing a
  stair costs nearly nothing."""

PRESETS: dict[str, dict[str, Preset]] = {
    "flat": {p.name: p for p in FLAT_PRESETS},
    "rough": {p.name: p for p in ROUGH_PRESETS},
}
"""Each task's presets by name; "default" first."""

DEFAULT_PRESET = "default"

ROUGH_ONLY = (
    "terrain",
    "curriculum",
    "height_scan",
    "heightfield_soles",
    "heightfield_sole_grid",
    "heightfield_sole_radius_m",
)
"""EnvConfig fields only the rough task reads: refused as overrides of the flat task (they would do nothing)."""

RUN_TIME_FIELDS = {
    "task": "the task is the command's: footforge train flat|rough",
    "feet": "--feet",
    "policy": "--policy",
    "physics": "--physics",
    "build_dir": "--build-root",
}
"""EnvConfig fields that no override sets, and the flag that does."""


def preset(task: str, name: str) -> Preset:
    """The task's preset called `name`.

    Raises:
      InputError: no such preset for the task.
    """
    try:
        return PRESETS[task][name]
    except KeyError:
        raise InputError(
            f"--preset {name}: no such preset for the {task} task", fix=f"use one of {', '.join(PRESETS.get(task, {}))}"
        ) from None


def resolve(
    task: str, feet: str, policy: str, preset_name: str = DEFAULT_PRESET, overrides=(), *, source: str = "--set"
):
    """(EnvConfig, PPOConfig) of the task's defaults for `feet` and `policy`, with the preset's
    overrides and then `overrides` applied (errors name `source`, the flag that gave them).

    Raises:
      InputError: an unknown preset, or an override that names no field or gives a value its field
        cannot hold.
    """
    from footforge import envs
    from footforge.rl.config import default_ppo

    chosen = preset(task, preset_name)
    env, ppo = envs.default_config(task, feet, policy), default_ppo(task)
    env, ppo = apply_overrides(env, ppo, chosen.overrides, source=f"preset '{chosen.name}'")
    return apply_overrides(env, ppo, overrides, source=source)


def apply_overrides(env, ppo, overrides, *, source: str = "--set"):
    """(env, ppo) with each `section.field=value` of `overrides` applied in order, then checked
    through config.json's form (the resolved configuration must survive to_dict/from_dict)."""
    from footforge import envs
    from footforge.rl.config import PPOConfig, env_config_from_dict, from_dict, to_dict

    for text in overrides:
        path, value_text = parse(text, source)
        if path[0] == "ppo":
            ppo = _assign(ppo, path[1:], value_text, text, source)
            continue
        if len(path) == 2 and path[1] in RUN_TIME_FIELDS:
            raise InputError(f"{source} {text}: env.{path[1]} is not an override", fix=RUN_TIME_FIELDS[path[1]])
        if env.task != "rough" and path[1] in ROUGH_ONLY:
            raise InputError(
                f"{source} {text}: env.{path[1]} is the rough task's; the {env.task} task has no terrain",
                fix="leave it out, or train the rough task",
            )
        if path[1:] == ("contact_model",):  # the contact model with the physics it needs (--contact-model)
            model = _parsed(value_text, env.contact_model, _hint(type(env), "contact_model"), text, source)
            env = envs.with_contact_model(replace(env, **envs.physics(env.feet, model)), model)
        elif path[1:] == ("float64_physics",):
            on = _parsed(value_text, env.float64_physics, bool, text, source)
            env = envs.with_float64_physics(env, on)
        else:
            env = _assign(env, path[1:], value_text, text, source)
    if env.task == "rough":
        env.terrain.check()
    if env_config_from_dict(to_dict(env)) != env or from_dict(PPOConfig, to_dict(ppo)) != ppo:
        raise InputError(
            f"{source}: the configuration does not survive config.json's form",
            fix="report this: an override set a value config.json cannot hold",
        )
    return env, ppo


def parse(text: str, source: str = "--set") -> tuple[tuple[str, ...], str]:
    """('env' or 'ppo', field, ...), value text of one `section.field=value`."""
    name, sep, value = text.partition("=")
    path = tuple(name.strip().split("."))
    if not sep or len(path) < 2 or path[0] not in ("env", "ppo") or not all(path):
        raise InputError(
            f"{source} {text}: expected SECTION.FIELD=VALUE with SECTION env or ppo",
            fix="e.g. --set ppo.entropy_cost=0.001 or --set env.commands.resample_s=10 "
            "(the fields: a run's config.json)",
        )
    return path, value.strip()


def _assign(config, path: tuple[str, ...], value_text: str, text: str, source: str):
    """`config` (a frozen dataclass) with the leaf at `path` set from `value_text`."""
    saved = [f.name for f in fields(config) if f.metadata.get("saved", True)]
    name = path[0]
    if name not in saved:
        close = difflib.get_close_matches(name, saved, n=3)
        raise InputError(
            f"{source} {text}: {type(config).__name__} has no field '{name}'",
            fix=f"did you mean {' or '.join(close)}?" if close else f"its fields: {', '.join(saved)}",
        )
    current = getattr(config, name)
    if len(path) == 2 and isinstance(current, dict):  # a mapping of values: a reward term's params
        key = path[1]
        if key not in current:
            close = difflib.get_close_matches(key, list(current), n=3)
            raise InputError(
                f"{source} {text}: '{name}' has no '{key}'",
                fix=f"did you mean {' or '.join(close)}?" if close else f"its keys: {', '.join(current) or 'none'}",
            )
        value = _parsed(value_text, current[key], _type_of(current[key]), text, source)
        return replace(config, **{name: {**current, key: value}})
    if len(path) > 1:
        if not is_dataclass(current):
            raise InputError(f"{source} {text}: '{name}' is a value, not a section", fix=f"set {name}=VALUE")
        return replace(config, **{name: _assign(current, path[1:], value_text, text, source)})
    if is_dataclass(current):
        leaves = [f.name for f in fields(current) if f.metadata.get("saved", True)]
        raise InputError(
            f"{source} {text}: '{name}' is a section", fix=f"set one of its fields: {name}." + f", {name}.".join(leaves)
        )
    return replace(config, **{name: _parsed(value_text, current, _hint(type(config), name, current), text, source)})


def _hint(cls, name: str, current=None):
    """The field's type hint, or (where its module names types only for type checkers, as
    envs.terms does) the type of its current value."""
    try:
        hint = typing.get_type_hints(cls)[name]
    except NameError:
        return _type_of(current)
    # A union of a number and a tuple (an observation group's scale): the form the field holds now.
    is_union = typing.get_origin(hint) in (typing.Union, types.UnionType)
    args = [a for a in typing.get_args(hint) if a is not type(None)] if is_union else []
    if len(args) > 1 and current is not None:
        return _type_of(current) if type(None) not in typing.get_args(hint) else _type_of(current) | None
    return hint


def _type_of(value):
    if isinstance(value, bool):
        return bool
    if isinstance(value, tuple):
        return tuple[int, ...] if value and all(isinstance(v, int) for v in value) else tuple[float, ...]
    return type(value)


def _parsed(value_text: str, current, hint, text: str, source: str):
    """`value_text` read as the type of the field (its annotation `hint`, its current value)."""
    optional = type(None) in typing.get_args(hint)
    if value_text.lower() in ("none", "null"):
        if optional:
            return None
        raise InputError(f"{source} {text}: this field cannot be none", fix="give a value")
    inner = [a for a in typing.get_args(hint) if a is not type(None)] if optional else [hint]
    kind = inner[0] if len(inner) == 1 else hint
    try:
        return _converted(value_text, kind)
    except _NotA as e:
        example = ",".join(map(str, current)) if isinstance(current, tuple) else current
        raise InputError(
            f"{source} {text}: '{value_text}' is not {e}", fix=f"e.g. {text.partition('=')[0]}={example}"
        ) from None
    except TypeError:
        raise InputError(
            f"{source} {text}: this field ({hint}) cannot be set from the command line", fix="leave it at its default"
        ) from None


class _NotA(ValueError):
    """A value that is not what its field holds; the message says what it should be."""


_WORDS = {"true": True, "1": True, "yes": True, "on": True, "false": False, "0": False, "no": False, "off": False}


def _converted(value_text: str, kind):
    """`value_text` as `kind` (a field's type); _NotA names what it should be, TypeError a type no
    override sets."""

    def number(text: str, as_int: bool):
        if as_int:
            try:
                return int(text)  # exactly, however large
            except ValueError:
                pass
        try:
            value = float(text)
        except ValueError:
            raise _NotA("a whole number" if as_int else "a number") from None
        if not math.isfinite(value):
            raise _NotA("a finite number")
        if as_int:
            if value != int(value):
                raise _NotA("a whole number")
            return int(value)
        return value

    if typing.get_origin(kind) is typing.Literal:
        if value_text not in typing.get_args(kind):
            raise _NotA(f"one of {', '.join(map(str, typing.get_args(kind)))}")
        return value_text
    if kind is bool:
        if value_text.lower() not in _WORDS:
            raise _NotA("true or false")
        return _WORDS[value_text.lower()]
    if kind in (int, float):
        return number(value_text, kind is int)
    if typing.get_origin(kind) is tuple:
        items = typing.get_args(kind)
        as_int = bool(items) and items[0] is int
        values = tuple(number(p, as_int) for p in value_text.strip("()[] ").split(",") if p.strip())
        if items and items[-1] is not Ellipsis and len(values) != len(items):
            raise _NotA(f"{len(items)} comma-separated numbers")
        return values
    if kind is str:
        return value_text
    raise TypeError(kind)


def recipe_of(saved: dict) -> tuple[str, tuple[str, ...]] | None:
    """(preset, overrides) a run's config.json records ("recipe"), or None for a run from before presets."""
    recipe = saved.get("recipe")
    if not isinstance(recipe, dict) or "preset" not in recipe:
        return None
    return recipe["preset"], tuple(recipe.get("overrides", ()))


def overrides_between(env, ppo, preset_name: str) -> list[str]:
    """The overrides that take the preset (on env's task, feet and policy type) to (env, ppo):
    the contact model and precision first (they bring physics of their own), then every leaf that
    still differs; resolve(..., preset_name, overrides_between(...)) gives (env, ppo) back. The
    run-time choices (physics, build_dir) are not compared.

    Raises:
      InputError: a difference no override can express (it is reported, not dropped).
    """
    from footforge.rl.config import config_differences, to_dict

    def leaves(tree: dict, prefix: str = "") -> dict[str, object]:
        out: dict[str, object] = {}
        for key, value in tree.items():
            out |= leaves(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}": value}
        return out

    def text(value) -> str:
        if isinstance(value, (list, tuple)):
            return ",".join(map(repr, value))
        return (
            "none"
            if value is None
            else str(value).lower()
            if isinstance(value, bool)
            else repr(value)
            if isinstance(value, float)
            else str(value)
        )

    target = leaves(to_dict(replace(env, physics="mjx", build_dir=None)), "env.") | leaves(to_dict(ppo), "ppo.")
    overrides: list[str] = []
    for name in ("env.contact_model", "env.float64_physics"):
        base_env, base_ppo = resolve(env.task, env.feet, env.policy, preset_name, overrides)
        base = leaves(to_dict(replace(base_env, physics="mjx", build_dir=None)), "env.")
        if base[name] != target[name]:
            overrides.append(f"{name}={text(target[name])}")
    base_env, base_ppo = resolve(env.task, env.feet, env.policy, preset_name, overrides)
    base = leaves(to_dict(replace(base_env, physics="mjx", build_dir=None)), "env.") | leaves(to_dict(base_ppo), "ppo.")
    overrides += [f"{key}={text(value)}" for key, value in target.items() if base.get(key) != value]
    got_env, got_ppo = resolve(env.task, env.feet, env.policy, preset_name, overrides)
    left = config_differences(
        {"env": to_dict(replace(got_env, physics=env.physics, build_dir=env.build_dir)), "ppo": to_dict(got_ppo)},
        {"env": to_dict(env), "ppo": to_dict(ppo)},
    )
    if left:
        raise InputError(f"no overrides of preset '{preset_name}' give this configuration: {'; '.join(left)}")
    return overrides


def closest_recipe(env, ppo) -> tuple[str, list[str]]:
    """(preset, overrides) that give (env, ppo) with the fewest overrides: the recipe of a run
    trained before presets (or outside footforge train)."""
    recipes = []
    for name in PRESETS[env.task]:
        try:
            recipes.append((name, overrides_between(env, ppo, name)))
        except InputError:
            continue  # a difference this preset's overrides cannot express: another may
    if not recipes:
        raise InputError("no preset and overrides give this configuration")
    return min(recipes, key=lambda recipe: len(recipe[1]))


def command_line(env, recipe: tuple[str, tuple[str, ...] | list[str]]) -> str:
    """The `footforge train` command that trains this recipe from scratch."""
    preset_name, overrides = recipe
    return (
        f"footforge train {env['task']} --feet {env['feet']} --policy {env['policy']} --preset {preset_name}"
        + "".join(f" --set {o}" for o in overrides)
        + " --out RUN"
    )


def describe(task: str) -> str:
    """The task's presets, one per line, for --help."""
    return "; ".join(f"{p.name}: {p.summary}" for p in PRESETS[task].values())
