"""The policies committed under policies/ load with today's code (configs upgraded, weights
intact by their manifests) and are what policies/README.md says: each was evaluated on its own
feet and walks there by the verdict its evaluation recorded, and still walks there when rolled
out with today's code (a few robots, a few seconds)."""

import importlib.util
import json

import pytest

from footforge.rl.checkpoints import checkpoint_problem
from footforge.rl.policy_files import load_policy_parameters

from conftest import REPO

_spec = importlib.util.spec_from_file_location("shipped_evaluations", REPO / "scripts/shipped_evaluations.py")
shipped_evaluations = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(shipped_evaluations)

SHIPPED = [run.name for run in shipped_evaluations.shipped()]
"""The flat policies shipped, as scripts/shipped_evaluations.py selects them; a finished rough policy is judged
by its evaluation over the terrain's tiles (policies/README.md)."""


def test_the_shipped_policies_are_listed():
    readme = (REPO / "policies/README.md").read_text()
    assert SHIPPED and all(f"`{name}`" in readme for name in SHIPPED), SHIPPED


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_policy_loads_and_walks_on_its_own_feet(name):
    folder = REPO / "policies" / name
    saved = load_policy_parameters(folder / "policy")
    progress = json.loads((folder / "progress.json").read_text())
    assert saved.global_step == progress["global_step"] > 0
    # Its weights once: policy/ (intact by its manifest), no checkpoints/ (--resume continues from policy/).
    assert checkpoint_problem(folder / "policy") is None and not (folder / "checkpoints").exists()
    assert saved.env.feet in name and saved.env.task in name and saved.env.policy in name.split("_")
    evaluated = json.loads((folder / "evaluation/metrics.json").read_text())
    (own,) = [r for r in evaluated if r["feet"] == saved.env.feet]
    assert own["walking"]["verdict"] == "walks" and own["num_envs"] >= 32 and own["seconds"] >= 20
    text = (folder / "evaluation/policy_card.md").read_text()
    line = next(row for row in text.splitlines() if row.startswith(f"- on {saved.env.feet} feet:"))
    assert "walks:" in line, line


ROLLOUT_ROBOTS, ROLLOUT_SECONDS = 4, 4.0


def _roll_out(name, built, out, seed=0):
    """`footforge evaluate` of shipped policy `name` on its own feet with the C engine, ROLLOUT_ROBOTS
    robots for ROLLOUT_SECONDS (`seed`): its metrics.json's bytes."""
    from footforge.cli.main import main

    feet = load_policy_parameters(REPO / "policies" / name / "policy").env.feet
    command = ["evaluate", "--policy", str(REPO / "policies" / name), "--num-envs", str(ROLLOUT_ROBOTS)]
    command += ["--seconds", str(ROLLOUT_SECONDS), "--seed", str(seed), "--physics", "mujoco"]
    assert main([*command, "--build-root", str(built[feet][0].parent), "--out", str(out)]) == 0
    return (out / "metrics.json").read_bytes()


@pytest.fixture(scope="module")
def first_rollouts(built, tmp_path_factory):
    """A shipped policy's rollout (_roll_out, seed 0), made once when first asked for: name -> metrics.json bytes."""
    root = tmp_path_factory.mktemp("rollouts")
    made: dict[str, bytes] = {}

    def rollout(name: str) -> bytes:
        if name not in made:
            made[name] = _roll_out(name, built, root / name)
        return made[name]

    return rollout


SLOW_ROLLOUTS = {"flat_ball_B_cpu", "flat_aff_BH", "flat_aof_BH"}
"""Rolled out among the slow tests, each about 20-26 s of the default run's 6 minutes: flat_ball_B_cpu, which
test_an_evaluation_repeats_byte_for_byte rolls out three times there, and the haptic policies (the default run
keeps a rollout of each adaptive feet's B policy)."""


@pytest.mark.parametrize(
    "name", [pytest.param(name, marks=pytest.mark.slow) if name in SLOW_ROLLOUTS else name for name in SHIPPED]
)
def test_a_shipped_policy_walks_on_its_own_feet_when_rolled_out(name, first_rollouts):
    """Each shipped policy rolled out now, not read from its recorded evaluation: `footforge
    evaluate` on its own feet with the C engine, 4 robots for 4 s (seed 0). Too short for the full
    verdict (its uptime and stance shares are 20-s figures, and the first second is the start from
    rest), so it asks what 4 s can show: no robot falls or diverges, the base rides at least
    verdict.MIN_BASE_HEIGHT_M high, and the forward error is within the verdict's
    MAX_FORWARD_ERROR_MPS."""
    from footforge.rl import verdict

    feet = load_policy_parameters(REPO / "policies" / name / "policy").env.feet
    (result,) = json.loads(first_rollouts(name))
    assert (result["feet"], result["num_envs"], result["seconds"]) == (feet, ROLLOUT_ROBOTS, ROLLOUT_SECONDS)
    walking = result["walking"]
    assert result["falls"] == 0 and result["diverged"] == 0 and walking["uptime"] == 1.0, result["fall_times_s"]
    assert walking["base_height_m"] >= verdict.MIN_BASE_HEIGHT_M, walking
    assert walking["forward_error_mps"] <= verdict.MAX_FORWARD_ERROR_MPS, walking


@pytest.mark.slow  # two more evaluations: about 30 s on 2 cores
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_an_evaluation_repeats_byte_for_byte(built, tmp_path):
    """The same policy, seed and robots give the same metrics.json, byte for byte (the C engine in
    float64, its results independent of its threads; every draw seeded), and another seed gives
    other figures (so the comparison can fail). The issue's differing figures came from code that
    changed between the card and the rerun, not from the rerun."""
    first = _roll_out("flat_ball_B_cpu", built, tmp_path / "first")
    assert _roll_out("flat_ball_B_cpu", built, tmp_path / "again") == first
    assert _roll_out("flat_ball_B_cpu", built, tmp_path / "other", seed=1) != first


def test_the_tables_of_shipped_policies_are_their_recorded_evaluations():
    """README.md's and policies/README.md's tables are what scripts/shipped_evaluations.py writes from
    the committed evaluations (so a regenerated evaluation cannot leave a stale caption behind)."""
    module = shipped_evaluations
    expected = module.table(module.shipped())
    for path in module.TABLES:
        text = path.read_text()
        block = text.split(module.START, 1)[1].split(module.END, 1)[0]
        assert block.strip() == expected.strip(), f"{path}: run python scripts/shipped_evaluations.py --tables-only"
    for name in SHIPPED:
        assert f"`policies/{name}`" in expected


def test_a_fine_tuned_policy_counts_the_steps_it_went_on_from(tmp_path):
    """`footforge play` names a policy's steps in all: flat_aof_B's own 5.04 M steps plus the 30.2 M of the runs
    it went on from (config.json's "initialised_from"); a policy trained from scratch, or a copy outside its
    run, has only its own."""
    from footforge.rl.policy_files import steps_in_all

    aof = REPO / "policies/flat_aof_B"
    own = json.loads((aof / "policy/footforge.json").read_text())["global_step"]
    before = json.loads((aof / "config.json").read_text())["initialised_from"]["steps_before"]
    assert before > 0 and steps_in_all(aof / "policy", own) == own + before
    ball = REPO / "policies/flat_ball_B_cpu/policy"
    assert steps_in_all(ball, 123) == 123
    import shutil

    shutil.copytree(aof / "policy", tmp_path / "policy")  # outside its run: no config.json beside it
    assert steps_in_all(tmp_path / "policy", own) == own


def test_an_evaluation_is_lightened_to_its_one_gif_and_the_cards_links_follow(tmp_path, monkeypatch):
    """light(): the strips and every GIF but the kept one go, with the card's lines linking them; a rough
    evaluation keeps the GIF on stairs (KEPT_VIDEO), a flat one the plain walk."""
    module = shipped_evaluations
    monkeypatch.setattr(module, "REPO", tmp_path)
    shrunk = []
    monkeypatch.setattr("footforge.rl.render.shrink_gif", lambda path, max_bytes: shrunk.append(path.name) or (1, 2, 3))
    for task in ("flat", "rough"):
        folder = tmp_path / task
        folder.mkdir()
        names = ["video_0.gif", "video_1.gif", "video_0_stairs_up.gif", "video_0_stepping_stones.gif", "strip_0.png"]
        for name in names + ["metrics.json", "contacts_0.png"]:
            (folder / name).write_bytes(b"x")
        card = "# card\n" + "".join(f"- [{n}]({n})\n" for n in names + ["contacts_0.png"])
        (folder / "policy_card.md").write_text(card)
        module.light(folder, keep=module.KEPT_VIDEO[task])
        kept = module.KEPT_VIDEO[task]
        assert sorted(p.name for p in folder.iterdir()) == sorted(
            [kept, "metrics.json", "contacts_0.png", "policy_card.md"]
        )
        assert (
            folder / "policy_card.md"
        ).read_text() == f"# card\n- [{kept}]({kept})\n- [contacts_0.png](contacts_0.png)\n"
    assert shrunk == ["video_0.gif", "video_0_stairs_up.gif"]


def test_rough_with_the_flat_tables_or_the_closed_chain_is_refused_before_any_work(capsys):
    for flag in ("--tables-only", "--closed-chain"):
        with pytest.raises(SystemExit) as exit_:
            shipped_evaluations.main(["--rough", flag])
        assert exit_.value.code == 2 and "--rough writes no table" in capsys.readouterr().err
