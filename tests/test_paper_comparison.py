"""scripts/paper_comparison.py: Figure 8 one pair at a time, done pairs kept, the table joined at the end."""

from __future__ import annotations

import importlib.util
import json
import shutil
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("paper_comparison", REPO / "scripts/paper_comparison.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def script(monkeypatch):
    """The script with footforge evaluate replaced by a recorded fake that writes a shipped result as the pair's."""
    from footforge.atomic import write_json

    module = _script()
    calls = []
    shipped = json.loads((REPO / "policies/flat_aof_B/evaluation/metrics.json").read_text())[0]

    def fake(policy, feet, folder, wanted, args):
        calls.append((policy.parent.name, feet, args.num_envs, args.seed))
        folder.mkdir(exist_ok=True)
        result = shipped | {"policy": str(policy), "feet": feet, "num_envs": args.num_envs, "falls": len(calls)}
        (folder / "metrics.json").write_text(json.dumps([result]))
        write_json(folder / "pair.json", wanted)
        return 0

    monkeypatch.setattr(module, "evaluate_pair", fake)
    return module, calls


def test_pairs_are_evaluated_once_and_joined_in_order(script, tmp_path):
    module, calls = script
    out = tmp_path / "cmp"
    pairs = ["--pairs", "flat_aof_B:aof", "flat_aff_B:aof"]
    assert module.main(["--out", str(out), *pairs, "--num-envs", "4"]) == 0
    assert calls == [("flat_aof_B", "aof", 4, 0), ("flat_aff_B", "aof", 4, 0)]
    rows = [line for line in (out / "comparison.md").read_text().splitlines() if line.startswith("| flat_")]
    assert [row.split("|")[1].strip() for row in rows] == ["flat_aof_B", "flat_aff_B"]
    assert [r["falls"] for r in json.loads((out / "metrics.json").read_text())] == [1, 2]
    assert (out / "comparison.png").stat().st_size > 0

    calls.clear()  # the same pairs and settings again: nothing to evaluate, the table rejoined
    assert module.main(["--out", str(out), *pairs, "--num-envs", "4"]) == 0
    assert calls == []
    assert module.main(["--out", str(out), *pairs, "--num-envs", "4", "--seed", "1"]) == 0  # other settings: again
    assert calls == [("flat_aof_B", "aof", 4, 1), ("flat_aff_B", "aof", 4, 1)]


def test_a_changed_policy_is_evaluated_again(script, tmp_path):
    module, calls = script
    policy = tmp_path / "run" / "policy"
    policy.parent.mkdir()
    shutil.copytree(REPO / "policies/flat_aof_B/policy", policy)
    out = tmp_path / "cmp"
    argv = ["--out", str(out), "--pairs", f"{policy.parent}:aof"]
    assert module.main(argv) == 0 and len(calls) == 1
    (policy / "footforge.json").write_text((policy / "footforge.json").read_text() + " ")
    assert module.main(argv) == 0 and len(calls) == 2


def test_a_spent_budget_leaves_pairs_for_the_next_call(script, tmp_path, capsys, monkeypatch):
    module, calls = script
    out = tmp_path / "cmp"
    argv = ["--out", str(out), "--pairs", "flat_aof_B:aof", "flat_aff_B:aff"]
    clock = iter([0.0, 0.0, 0.0, 600.0, 600.0, 600.0])  # start, pair 1 (starts at 0, takes 10 min), pair 2, end
    monkeypatch.setattr(module, "clock", lambda: next(clock))
    assert module.main([*argv, "--max-minutes", "15"]) == 1  # 10 + 10 > 15: the second waits
    monkeypatch.setattr(module, "clock", time.monotonic)
    assert calls == [("flat_aof_B", "aof", 1024, 0)]
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["left"] == ["flat_aff_B_on_aff"] and not (out / "comparison.md").exists()
    assert module.main(argv) == 0 and len(calls) == 2


def test_a_users_folder_and_bad_pairs_are_refused_before_any_work(script, tmp_path):
    module, calls = script
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    assert module.main(["--out", str(mine), "--pairs", "flat_aof_B:aof"]) == 2
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt"]
    assert module.main(["--out", str(tmp_path / "new"), "--pairs", "no_such_policy:aof"]) == 2
    assert not (tmp_path / "new").exists()
    with pytest.raises(SystemExit) as e:
        module.main(["--out", str(tmp_path / "new"), "--pairs", "flat_aof_B:hoof"])
    assert e.value.code == 2
    other = tmp_path / "runs" / "flat_aof_B"  # a run folder of the shipped policy's name: one pair folder for two
    shutil.copytree(REPO / "policies/flat_aof_B/policy", other / "policy")
    assert module.main(["--out", str(tmp_path / "new"), "--pairs", "flat_aof_B:aof", f"{other}:aof"]) == 2
    assert not (tmp_path / "new").exists()
    assert calls == []


def test_the_rough_comparison_takes_the_rough_policies_trained_so_far(script, tmp_path, capsys, monkeypatch):
    """--rough: the paper's rough pairs at 17.5 s, those whose policy has a finished policy/ under
    policies/; the others (not trained, or in training with checkpoints only) named, in the summary and under
    the joined table. With none trained it is refused (exit 2) before any work."""
    module, calls = script
    policies = tmp_path / "policies"
    monkeypatch.setattr(module, "POLICIES", policies)
    out = tmp_path / "cmp"
    assert module.main(["--rough", "--out", str(out)]) == 2 and not out.exists()
    shutil.copytree(REPO / "policies/flat_aof_B/policy", policies / "rough_aof_P" / "policy")
    shutil.copytree(REPO / "policies/flat_aof_B/policy", policies / "rough_ball_P" / "policy")
    (policies / "rough_aof_PH" / "checkpoints" / "000000000064").mkdir(parents=True)  # still in training
    assert module.main(["--rough", "--out", str(out), "--num-envs", "8"]) == 0
    assert calls == [("rough_ball_P", feet, 8, 0) for feet in ("ball", "aff", "aof")] + [("rough_aof_P", "aof", 8, 0)]
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert "rough_aof_PH:aof" in summary["not_trained"] and "rough_aof_P:aof" not in summary["not_trained"]
    assert len(summary["not_trained"]) == len(module.ROUGH_PAIRS) - 4
    assert json.loads((out / "rough_aof_P_on_aof" / "pair.json").read_text())["seconds"] == module.ROUGH_SECONDS
    assert "Not trained yet, left out: " in (out / "comparison.md").read_text()


def test_a_pair_the_policys_own_evaluation_holds_is_reused_not_evaluated(script, tmp_path, capsys):
    """A row of the policy's evaluation/metrics.json with the same digest, feet, robots, seconds and seed is
    the pair's result; a row of other robots, or of other parameters (a changed policy), is not."""
    from footforge.rl.policy_files import policy_digest

    module, calls = script
    run = tmp_path / "rough_ball_P"
    shutil.copytree(REPO / "policies/flat_aof_B/policy", run / "policy")
    shipped = json.loads((REPO / "policies/flat_aof_B/evaluation/metrics.json").read_text())[0]
    digest = policy_digest(run)
    row = shipped | {"policy_sha256": digest, "num_envs": 8, "seconds": 17.5, "seed": 0, "falls": 99}
    row["physics"] = "mujoco"  # the engine this CPU's evaluations use
    rows = [row | {"feet": "aff"}, row | {"feet": "aof", "num_envs": 16}, row | {"feet": "ball", "policy_sha256": "0"}]
    rows += [row | {"feet": "aof", "physics": "mjx"}, "not a row"]  # another engine's: not mixed into the table
    (run / "evaluation").mkdir()
    (run / "evaluation" / "metrics.json").write_text(json.dumps(rows))
    out = tmp_path / "cmp"
    pairs = [f"{run}:{feet}" for feet in ("aff", "aof", "ball")]
    assert module.main(["--out", str(out), "--pairs", *pairs, "--num-envs", "8", "--seconds", "17.5"]) == 0
    assert calls == [("rough_ball_P", "aof", 8, 0), ("rough_ball_P", "ball", 8, 0)]
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["reused"] == ["rough_ball_P_on_aff"]
    assert summary["evaluated"] == ["rough_ball_P_on_aof", "rough_ball_P_on_ball"]
    assert json.loads((out / "metrics.json").read_text())[0] == rows[0]  # the recorded row, joined first
    calls.clear()  # done pairs, the reused one included, are kept
    assert module.main(["--out", str(out), "--pairs", *pairs, "--num-envs", "8", "--seconds", "17.5"]) == 0
    assert calls == []
    # A pair's folder holding a user's file is not replaced by a reuse: that pair fails, the others go on.
    mine = out / "rough_ball_P_on_aff"
    shutil.rmtree(mine)
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    assert module.main(["--out", str(out), "--pairs", *pairs, "--num-envs", "8", "--seconds", "17.5"]) == 1
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["failed"] == ["rough_ball_P_on_aff"] and (mine / "notes.txt").read_text() == "mine"


def test_footforge_does_not_replace_the_comparison_folder_unforced(script, tmp_path):
    """A comparison's folder holds pairs of many calls: footforge's commands refuse to replace it, as a run folder."""
    from footforge.errors import InputError
    from footforge.outputs import check_output_folder

    module, _ = script
    out = tmp_path / "cmp"
    assert module.main(["--out", str(out), "--pairs", "flat_aof_B:aof"]) == 0
    with pytest.raises(InputError, match="filled over many calls"):
        check_output_folder(out)
    assert check_output_folder(out, force=True) == out


@pytest.mark.slow
def test_one_real_pair_end_to_end(tmp_path):
    """The real footforge evaluate of one pair, tiny (4 robots x 0.5 s), then the joined table."""
    from footforge.rl.policy_files import policy_digest

    module = _script()
    out = tmp_path / "cmp"
    argv = ["--out", str(out), "--pairs", "flat_aff_B:aff", "--num-envs", "4", "--seconds", "0.5"]
    assert module.main(argv) == 0
    (result,) = json.loads((out / "metrics.json").read_text())
    assert (result["feet"], result["num_envs"], result["seconds"]) == ("aff", 4, 0.5)
    assert result["policy_sha256"] == policy_digest(REPO / "policies/flat_aff_B")  # what a later call may reuse
    assert json.loads((out / "flat_aff_B_on_aff" / "metrics.json").read_text()) == [result]


def test_a_policy_named_under_policies_is_recorded_relative_to_the_repository(monkeypatch, tmp_path):
    """Run from the repository, a policy named by its folder under policies/ is the relative
    policies/<name>/policy (what the evaluation's rows record, the same on every clone); run from another
    folder, the repository's parent or one outside it, the absolute path; a path the user gives is kept as
    given."""
    module = _script()
    monkeypatch.chdir(REPO)
    assert module.policy_dir("flat_aof_B") == Path("policies/flat_aof_B/policy")
    for elsewhere in (REPO.parent, tmp_path):
        monkeypatch.chdir(elsewhere)
        assert module.policy_dir("flat_aof_B") == REPO / "policies/flat_aof_B/policy"
    shutil.copytree(REPO / "policies/flat_aof_B/policy", tmp_path / "mine" / "policy")
    assert module.policy_dir("mine") == Path("mine/policy")
