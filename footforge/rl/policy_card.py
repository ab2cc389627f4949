"""A one-page summary of a trained policy and its evaluation: policy_card.md.

footforge evaluate writes one per policy next to its metrics and plots. Read from the policy
folder: footforge.json (the environment and PPO configurations, the global step, and from
training the wall time and machine) and, where the policy folder sits in its run folder,
../progress.json (resumes, the last evaluation's return, a wall-time stop) and ../config.json (the
run it was initialised from, with --init-from). Runs trained before
the wall time and machine were recorded say "not recorded". Plots are linked by their path
relative to the card, which lies in the same folder.
"""

from __future__ import annotations

import json
from pathlib import Path

from footforge.envs import engine
from footforge.rl.config import steps_before
from footforge.rl.evaluate import (
    AFTER_EVENT_S,
    INDEX_UNITS,
    INDICES,
    command_falls_cell,
    falls_cell,
    terrain_levels_markdown,
)
from footforge.tables import markdown_table


def card_name(policy_index: int, policies: int) -> str:
    """policy_card.md for a single policy; policy_card_<k>.md (k: its place in --policy) for several."""
    return "policy_card.md" if policies == 1 else f"policy_card_{policy_index}.md"


def policy_card(policy_dir: Path, evaluations: list[tuple[int, dict]], files: list[str]) -> str:
    """The card (markdown) of `policy_dir` from its evaluations, each (index of the result in the
    evaluation's output, evaluate()'s result), and the output's file names (to link the plots)."""
    from footforge.rl.policy_files import policy_meta

    policy_dir = Path(policy_dir)
    meta = policy_meta(policy_dir)
    env = meta["env"]
    progress_file = policy_dir.resolve().parent / "progress.json"
    progress = json.loads(progress_file.read_text()) if progress_file.is_file() else {}
    config_file = policy_dir.resolve().parent / "config.json"
    try:  # a run records its recipe there (rl.presets), and a run started with --init-from its source
        run_config = json.loads(config_file.read_text()) if config_file.is_file() else {}
        origin, recipe = run_config.get("initialised_from"), run_config.get("recipe")
    except (OSError, ValueError, AttributeError):
        origin = recipe = None
    if origin:
        progress = progress | {"initialised_from": origin}
    if recipe:
        progress = progress | {"recipe": recipe}
    name = policy_dir.resolve().parent.name if policy_dir.resolve().name == "policy" else policy_dir.name
    lines = [
        f"# Policy card: {name}",
        "",
        f"`{policy_dir}`: {env['task']} task, {env['feet']} feet, policy type {env['policy']}",
        "",
    ]
    lines += ["## Training", ""] + markdown_table(["", ""], [(k, str(v)) for k, v in _training_rows(meta, progress)])
    lines += ["", "## Evaluation", ""]
    for _, r in evaluations:
        lines.append(
            f"- on {r['feet']} feet{' (zero-shot)' if r['feet'] != r['trained_on'] else ''}: "
            f"{r['num_envs']} robots, {r['seconds']:g} s, seed {r['seed']}, "
            f"physics {r.get('physics', 'mjx')}, {r['falls']} fell"
            + (f"; {r['walking']['line']}" if "walking" in r else "")
        )
    rows = [
        [f"{index} ({INDEX_UNITS[index]})"]
        + [f"{r['indices'][index]['mean']:.4g} ± {r['indices'][index]['std']:.4g}" for _, r in evaluations]
        for index in INDICES
    ]
    rows.append(["slippage (-)"] + [f"{r['slippage']:.4g}" for _, r in evaluations])
    rows.append(["falls"] + [falls_cell(r) for _, r in evaluations])
    if any("command_changes" in r for _, r in evaluations):
        rows.append(
            [f"new commands fallen after within {AFTER_EVENT_S:g} s, by change of velocity"]
            + [command_falls_cell(r) for _, r in evaluations]
        )
    rows.append(["verdict"] + [r["walking"]["line"] if "walking" in r else "not judged" for _, r in evaluations])
    lines += [""] + markdown_table(["index"] + [f"on {r['feet']}" for _, r in evaluations], rows)
    lines += [
        "",
        "Mean ± standard deviation over every policy step of every robot still standing "
        "(footforge/rl/evaluate.py defines the indices). The verdict (walks, stands or falls) comes "
        "from the forward error, the time up, the base height and each foot's share of the ground "
        "(footforge/rl/verdict.py).",
    ]
    for _, r in evaluations:
        if r.get("by_terrain"):
            lines += [
                "",
                f"Robots that crossed their tile and robots that fell, by terrain kind and level, on {r['feet']} "
                "feet (each robot spawned on one tile, commanded across it; one that crossed and then fell counts "
                "in both; level l: difficulty l / levels):",
                "",
                terrain_levels_markdown(r).rstrip("\n"),
            ]
    lines += [
        "",
        "## Plots",
        "",
    ]
    lines += [f"- {text}: [{f}]({f})" for text, f in _plots(evaluations, files)]
    return "\n".join(lines) + "\n"


def _training_rows(meta: dict, progress: dict) -> list[tuple[str, str]]:
    env, ppo = meta["env"], meta["ppo"]
    step = int(meta.get("global_step", 0))
    rows = [
        (
            "steps trained",
            f"{step:,} of {int(ppo['num_timesteps']):,}" + (" (freshly initialised, untrained)" if step == 0 else ""),
        )
    ]
    recipe = progress.get("recipe")
    if recipe:  # rl.presets: the preset and the overrides that give this configuration
        from footforge.rl.presets import command_line

        overrides = recipe.get("overrides", [])
        rows.append(
            (
                "recipe",
                f"preset `{recipe['preset']}`, "
                + (f"overrides {', '.join(f'`{o}`' for o in overrides)}" if overrides else "no overrides")
                + f": `{command_line(env, (recipe['preset'], overrides))}`",
            )
        )
    else:
        rows.append(("recipe", "not recorded (a run from before footforge train's presets)"))
    origin = progress.get("initialised_from")
    if origin:  # fine-tuned: train --init-from
        rows.append(
            (
                "started from",
                f"step {int(origin['step']):,} of {origin['run']} (--init-from): "
                f"{steps_before(origin) + step:,} steps in all",
            )
        )
    wall_s = meta.get("wall_s") or progress.get("wall_s_total")
    resumes = progress.get("resumes", 0)
    rows.append(
        (
            "wall time",
            (_duration(wall_s) if wall_s else "not recorded")
            + (f", over {resumes + 1} calls (--resume)" if resumes else ""),
        )
    )
    rows.append(("machine", _machine(meta.get("machine") or progress.get("machine"))))
    if progress.get("stopped"):
        rows.append(("stopped", progress["stopped"]))
    metrics = progress.get("metrics", {})
    if "eval/episode_reward" in metrics:
        rows.append(
            (
                "last training evaluation",
                f"return {metrics['eval/episode_reward']:.3f}, episode length "
                f"{metrics.get('eval/avg_episode_length', float('nan')):.0f} steps",
            )
        )
    rows.append(
        (
            "PPO",
            f"{ppo['num_envs']} robots x {ppo['unroll_length']} steps per iteration, "
            f"{ppo['num_minibatches']} minibatches of {ppo['batch_size']}, {ppo['num_updates_per_batch']} "
            f"epochs, learning rate {ppo['learning_rate']:g}"
            + (f" (adaptive KL {ppo['adaptive_kl']:g})" if ppo["adaptive_kl"] else "")
            + f", entropy {ppo['entropy_cost']:g}, discount {ppo['discounting']:g}, "
            f"GAE lambda {ppo['gae_lambda']:g}, clip {ppo['clipping_epsilon']:g}, seed {ppo['seed']}",
        )
    )
    rows.append(
        (
            "networks",
            f"policy {'-'.join(map(str, ppo['policy_hidden_layers']))}, value "
            f"{'-'.join(map(str, ppo['value_hidden_layers']))} (ELU), observations "
            + ("normalised" if ppo["normalize_observations"] else "raw")
            + (", privileged critic" if env.get("privileged_critic") else ""),
        )
    )
    unit = "rad/s" if env["action"] == "velocity" else "rad"
    control_hz = 1.0 / (env["sim_dt"] * env["decimation"])
    randomised = [k.removesuffix("_range") for k, v in env["randomization"].items() if v is not None]
    rows.append(
        (
            "environment",
            f"{env['action']} actions x {env['action_scale']:g} {unit}, clipped to "
            f"+-{env['action_clip']:g}; {control_hz:g} Hz control ({env['sim_dt'] * 1e3:g} ms x "
            f"{env['decimation']}); {env['episode_length_s']:g} s episodes; pushes "
            + (f"every {env['pushes']['interval_s']:g} s" if env["pushes"]["enabled"] else "off")
            + f"; randomised: {', '.join(randomised) or 'nothing'}; observation noise "
            + ("on" if env["observations"]["noise"] else "off")
            + f"; {env['contact_model']} contact model; trained on "
            + engine.describe(env.get("physics", "mjx")),
        )
    )
    return rows


def _duration(seconds: float) -> str:
    seconds = float(seconds)
    if seconds < 120:
        return f"{seconds:.0f} s"
    hours, minutes = divmod(round(seconds / 60), 60)
    return f"{hours} h {minutes} min" if hours else f"{minutes} min"


def _machine(machine: dict | None) -> str:
    if not machine:
        return "not recorded"
    return (
        f"{machine['devices']} x {machine['device_kind']} ({machine['backend']}, {machine['processes']} "
        f"process{'es' if machine['processes'] != 1 else ''}), {machine['cpu_cores']} CPU cores, "
        f"{machine['platform']}, jax {machine['jax']}"
    )


def _plots(evaluations: list[tuple[int, dict]], files: list[str]) -> list[tuple[str, str]]:
    """(what, file) of the plots and recordings of these evaluations, in the output's order."""
    out = [("indices of every evaluated policy", "comparison.png")] if "comparison.png" in files else []
    for i, r in evaluations:
        for f in files:
            stem = f.rsplit(".", 1)[0]
            if stem == f"contacts_{i}":
                out.append((f"feet contact schedule on {r['feet']}", f))
            elif stem.startswith(f"contacts_{i}_") and stem.split("_")[1] == str(i):
                kind = stem.split("_", 2)[2].replace("_", " ")
                out.append((f"feet contact schedule on {r['feet']}, {kind}", f))
            elif stem == f"push_response_{i}":
                out.append((f"push response on {r['feet']}", f))
            elif stem.startswith((f"video_{i}", f"strip_{i}")) and stem.split("_")[1] == str(i):
                kind = stem.split("_", 2)[2] if stem.count("_") > 1 else "walking"
                out.append(
                    (f"{'video' if stem.startswith('video') else 'frames'} on {r['feet']}, {kind.replace('_', ' ')}", f)
                )
    return out
