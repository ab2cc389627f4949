"""The policy card: training summary from the policy and run folders, the evaluation's indices,
plots linked by relative path. No simulation here: the evaluation tests (tests/test_rough.py,
and the slow one in tests/test_train.py) check the card that pipelines/evaluate.py writes."""

import json
import re

from footforge import envs
from footforge.rl.evaluate import INDICES
from footforge.rl.policy_card import card_name, policy_card
from footforge.rl.train import PPOConfig, to_dict


def _result(policy, feet, offset, trained_on="aof"):
    return {
        "policy": str(policy),
        "trained_on": trained_on,
        "feet": feet,
        "policy_type": "B",
        "num_envs": 8,
        "seconds": 2.0,
        "seed": 0,
        "task": "flat",
        "slippage": 0.125 + offset,
        "falls": 1,
        "indices": {name: {"mean": 0.1 * k + offset, "std": 0.01 * k} for k, name in enumerate(INDICES, 1)},
    }


def test_card_of_a_trained_run(tmp_path):
    run = tmp_path / "flat_aof_B"
    policy = run / "policy"
    policy.mkdir(parents=True)
    env, ppo = envs.default_config("flat", "aof", "B"), PPOConfig(num_timesteps=1_000_000)
    machine = {
        "backend": "gpu",
        "devices": 1,
        "device_kind": "NVIDIA H100",
        "processes": 1,
        "cpu_cores": 16,
        "platform": "Linux-6.1",
        "jax": "0.9.2",
    }
    (policy / "footforge.json").write_text(
        json.dumps(
            {"env": to_dict(env), "ppo": to_dict(ppo), "global_step": 983_040, "wall_s": 7384.0, "machine": machine}
        )
    )
    (run / "progress.json").write_text(
        json.dumps(
            {
                "global_step": 983_040,
                "resumes": 1,
                "stopped": "wall-time budget",
                "metrics": {"eval/episode_reward": 12.5, "eval/avg_episode_length": 1000.0},
            }
        )
    )
    files = [
        "comparison.png",
        "contacts_0.png",
        "push_response_0.png",
        "contacts_1.png",
        "push_response_1.png",
        "video_1.gif",
        "strip_1.png",
        "video_10.gif",
    ]
    results = [_result(policy, "aof", 0.0), _result(policy, "aff", 0.5)]
    results[0]["walking"] = {"line": "walks: trot, forward error 0.09 m/s"}  # evaluate()'s verdict
    card = policy_card(policy, list(enumerate(results)), files)

    assert card.startswith("# Policy card: flat_aof_B\n")
    assert "983,040 of 1,000,000" in card and "2 h 3 min, over 2 calls" in card
    assert "1 x NVIDIA H100 (gpu, 1 process), 16 CPU cores" in card and "wall-time budget" in card
    assert "return 12.500" in card and "policy 256-128-64" in card and "position actions x 0.5 rad" in card
    assert "50 Hz control (2.5 ms x 8)" in card and "randomised: nothing" in card and "stance contact model" in card
    for name in INDICES:
        row = next(line for line in card.splitlines() if line.startswith(f"| {name} ("))
        cells = row.split(" | ")[1:]
        assert cells[0].startswith(f"{results[0]['indices'][name]['mean']:.4g} ± ")
        assert cells[1].startswith(f"{results[1]['indices'][name]['mean']:.4g} ± ")
    assert "on aff feet (zero-shot)" in card and "| falls | 1/8 | 1/8 |" in card
    assert (
        "- on aof feet: 8 robots, 2 s, seed 0, physics mjx, 1 fell; walks: trot, forward error 0.09 m/s"
        in card.splitlines()
    )
    assert "| verdict | walks: trot, forward error 0.09 m/s | not judged |" in card
    links = re.findall(r"\]\(([^)]+)\)", card)
    assert links == [
        "comparison.png",
        "contacts_0.png",
        "push_response_0.png",
        "contacts_1.png",
        "push_response_1.png",
        "video_1.gif",
        "strip_1.png",
    ]  # not video_10: another result's


def test_card_of_a_fine_tuned_run_counts_the_source_s_steps(tmp_path):
    """A run started with --init-from counts its steps from 0; its card adds the source's."""
    run = tmp_path / "tuned"
    policy = run / "policy"
    policy.mkdir(parents=True)
    env, ppo = envs.default_config("flat", "aof", "B"), PPOConfig(num_timesteps=4_000_000)
    (policy / "footforge.json").write_text(
        json.dumps({"env": to_dict(env), "ppo": to_dict(ppo), "global_step": 3_526_656})
    )
    (run / "config.json").write_text(
        json.dumps(
            {"env": to_dict(env), "ppo": to_dict(ppo), "initialised_from": {"run": "/runs/aof", "step": 10_027_008}}
        )
    )
    card = policy_card(policy, [(0, _result(policy, "aof", 0.0))], [])
    assert "| started from | step 10,027,008 of /runs/aof (--init-from): 13,553,664 steps in all |" in card
    # A source that had itself been initialised from another run: the steps before this run are the lineage's.
    origin = {"run": "/runs/aof", "step": 10_027_008, "steps_before": 30_000_000}
    (run / "config.json").write_text(json.dumps({"env": to_dict(env), "ppo": to_dict(ppo), "initialised_from": origin}))
    card = policy_card(policy, [(0, _result(policy, "aof", 0.0))], [])
    assert "| started from | step 10,027,008 of /runs/aof (--init-from): 33,526,656 steps in all |" in card
    (run / "config.json").write_text(json.dumps({"env": to_dict(env), "ppo": to_dict(ppo)}))
    assert "started from" not in policy_card(policy, [(0, _result(policy, "aof", 0.0))], [])


def test_card_of_an_untrained_policy_says_what_was_not_recorded(tmp_path):
    policy = tmp_path / "policy"
    policy.mkdir()
    env, ppo = envs.default_config("flat", "ball", "B"), PPOConfig()
    (policy / "footforge.json").write_text(json.dumps({"env": to_dict(env), "ppo": to_dict(ppo), "global_step": 0}))
    card = policy_card(policy, [(0, _result(policy, "ball", 0.0, trained_on="ball"))], ["comparison.png"])
    assert "freshly initialised" in card and "| wall time | not recorded |" in card
    assert "| machine | not recorded |" in card and "zero-shot" not in card
    assert card_name(0, 1) == "policy_card.md" and card_name(2, 3) == "policy_card_2.md"


def test_card_of_a_rough_evaluation_tables_crossings_and_falls_by_kind_and_level(tmp_path):
    """A rough evaluation's robots by kind and level: each cell its tile's crossed/robots and falls, a
    level a kind lacks as '-'; a flat evaluation gets no such table."""
    from footforge.rl.evaluate import terrain_levels_markdown

    policy = tmp_path / "rough_aof_P" / "policy"
    policy.mkdir(parents=True)
    env = envs.default_config("rough", "aof", "P")
    (policy / "footforge.json").write_text(json.dumps({"env": to_dict(env), "ppo": to_dict(PPOConfig())}))
    rough = _result(policy, "aof", 0.0) | {"task": "rough"}
    tile = {"diverged": 0} | {name: 0.1 for name in INDICES}
    rough["by_terrain"] = {
        "stairs_up": {
            "0": tile | {"robots": 5, "falls": 1, "crossed": 4},
            "1": tile | {"robots": 4, "falls": 4},
        },  # crossings not counted
        "discrete": {"1": tile | {"robots": 3, "falls": 0, "crossed": 3}},
    }
    table = terrain_levels_markdown(rough).splitlines()
    assert table[0] == "| kind | level 0 | level 1 |"
    assert table[2:] == ["| discrete | - | 3/3, fell 0 |", "| stairs_up | 4/5, fell 1 | -/4, fell 4 |"]
    card = policy_card(policy, [(0, rough)], [])
    assert "\n".join(table) in card and "by terrain kind and level, on aof feet" in card
    assert terrain_levels_markdown(_result(policy, "aof", 0.0)) == ""
