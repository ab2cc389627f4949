"""The physics table of the contact models (footforge/envs/contact_physics.py): docs/defaults.md shows
it as it is, every contact model, feet, precision and ground resolves to a row and every row is
reached, its settings make physical sense, and the functions that set and check a configuration's
step and iterations hold it to them. No model is compiled."""

from dataclasses import replace
from itertools import product

import pytest

from footforge import envs
from footforge.envs import contact_physics
from footforge.envs.anymal import check_contact_model
from footforge.envs.config import EnvConfig
from footforge.envs.contact_physics import CONTACT_PHYSICS, as_markdown, resolve
from footforge.errors import InputError
from footforge.variants import FEET

from conftest import REPO

SECTION = "## Physics per contact model, feet and precision"
COMBINATIONS = list(product(envs.CONTACT_MODELS, FEET, (False, True), (False, True)))
"""(contact model, feet, float64_physics, on_heightfield): everything the environments can ask for."""


def _docs_table() -> str:
    """The first Markdown table under SECTION in docs/defaults.md."""
    text = (REPO / "docs" / "defaults.md").read_text()
    assert SECTION in text, f"docs/defaults.md has no '{SECTION}'"
    lines = text[text.index(SECTION) :].splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("|"))
    end = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    return "\n".join(lines[start:end]) + "\n"


def test_the_docs_table_is_the_code_s_table():
    """docs/defaults.md's table is as_markdown() of CONTACT_PHYSICS, row for row (regenerate it with
    `python -c "from footforge.envs.contact_physics import as_markdown; print(as_markdown())"`); a
    changed setting in either shows."""
    docs = _docs_table()
    assert docs == as_markdown(), "docs/defaults.md's physics table differs from envs.contact_physics.as_markdown()"
    assert len(docs.splitlines()) == 2 + len(CONTACT_PHYSICS)
    # The comparison sees a changed setting: AOF's float32 iterations 8/16 -> 16/16.
    i = CONTACT_PHYSICS.index(resolve("stance", "aof", float64_physics=False, on_heightfield=False))
    changed = (*CONTACT_PHYSICS[:i], replace(CONTACT_PHYSICS[i], min_iterations=(16, 16)), *CONTACT_PHYSICS[i + 1 :])
    assert as_markdown(changed) != docs


def test_every_combination_finds_a_row_and_every_row_is_some_combination_s():
    """The first match wins, so a row shadowed by those before it would be dead text; and the step and
    iterations do not depend on the ground, since envs.physics and envs.with_contact_model set them
    before a ground is chosen."""
    reached = set()
    for model, feet, float64, on_heightfield in COMBINATIONS:
        row = resolve(model, feet, float64, on_heightfield)
        assert row.contact_model == model
        reached.add(CONTACT_PHYSICS.index(row))
        plane = resolve(model, feet, float64, on_heightfield=False)
        assert (row.sim_dt_s, row.max_sim_dt_s, row.min_iterations) == (
            plane.sim_dt_s,
            plane.max_sim_dt_s,
            plane.min_iterations,
        ), (model, feet, float64)
    assert reached == set(range(len(CONTACT_PHYSICS)))


def test_stance_s_friction_and_normal_are_integrated_by_its_step():
    """Checked against MuJoCo's own rules, not the table: MuJoCo clamps a solref time constant to at
    least two steps, and the build's 4 ms then becomes 2 x the step. 'stance' held a ball robot still
    with a 5 ms time constant (2.5 ms step) and let a foot chatter with 10 ms (5 ms step): every
    'stance' row's longest step keeps it at 5 ms or less. A direct-form solref (-k, -b) needs a
    damping b the step integrates, at most 2 / (two steps) (800 1/s at 2.5 ms slid 256 mm), and a
    damping ratio b / (2 sqrt(k)) of at least 1, so a loaded sole settles without bouncing."""
    build_time_constant_s = 0.004
    stance = [r for r in CONTACT_PHYSICS if r.contact_model == "stance"]
    assert stance
    for row in stance:
        assert row.max_sim_dt_s is not None and row.sim_dt_s <= row.max_sim_dt_s
        if row.solref is None:
            assert max(build_time_constant_s, 2 * row.max_sim_dt_s) <= 0.005 + 1e-12, row
        else:
            stiffness, damping = -row.solref[0], -row.solref[1]
            assert stiffness > 0 and damping > 0, row
            assert damping <= 2 / (2 * row.max_sim_dt_s) + 1e-9, row
            assert damping / (2 * stiffness**0.5) >= 1.0, row


def test_stance_is_stiffer_than_fast_and_float64_no_softer_than_float32():
    """'stance' keeps more of the constraint force than MuJoCo's default and regularises friction less
    (impratio > 1); in float64, which solves the stiff impedance exactly enough, no feet is softer or
    given fewer iterations than in float32."""
    fast = resolve("fast", "ball", float64_physics=False, on_heightfield=False)
    assert fast.solimp == (0.9, 0.95, 0.001) and fast.impratio == 1.0  # MuJoCo's defaults
    for feet, on_heightfield in product(FEET, (False, True)):
        float32 = resolve("stance", feet, float64_physics=False, on_heightfield=on_heightfield)
        float64 = resolve("stance", feet, float64_physics=True, on_heightfield=on_heightfield)
        for row in (float32, float64):
            assert row.solimp[0] > fast.solimp[0] and row.solimp[1] > fast.solimp[1], row
            assert row.solimp[0] <= row.solimp[1] < 1.0 and row.impratio > fast.impratio, row
        assert all(a >= b for a, b in zip(float64.solimp[:2], float32.solimp[:2])), feet
        assert all(a >= b for a, b in zip(float64.min_iterations, float32.min_iterations)), feet
        assert float64.solref is None, feet  # the build's: float64 needs no softer normal


@pytest.mark.parametrize("task", ["flat", "rough"])
def test_every_row_s_step_and_iterations_are_what_configs_get_and_need(task):
    """envs.default_config (via envs.physics) and envs.with_float64_physics give every feet at least
    its row's iterations, at a step no longer than its row allows, and check_contact_model accepts
    that and refuses one iteration fewer or a longer step."""
    on_heightfield = task == "rough"
    for model, feet, float64 in product(envs.CONTACT_MODELS, FEET, (False, True)):
        row = resolve(model, feet, float64, on_heightfield)
        config = envs.with_float64_physics(envs.default_config(task, feet, "B", model), float64)
        assert config.contact_model == model and config.float64_physics == float64
        assert config.sim_dt == row.sim_dt_s, (model, feet)  # the row's own step
        if row.max_sim_dt_s is not None:
            assert config.sim_dt <= row.max_sim_dt_s
            with pytest.raises(InputError, match="needs sim_dt <="):
                check_contact_model(replace(config, sim_dt=2 * row.max_sim_dt_s), on_heightfield=on_heightfield)
        assert config.sim_dt * config.decimation == pytest.approx(0.02)
        minimum = row.min_iterations or contact_physics.DEFAULT_ITERATIONS
        assert config.solver_iterations >= minimum[0] and config.solver_ls_iterations >= minimum[1]
        check_contact_model(config, on_heightfield=on_heightfield)
        if row.min_iterations is None:
            check_contact_model(replace(config, solver_iterations=1, solver_ls_iterations=1))  # 'fast': any
            continue
        for fewer in (
            {"solver_iterations": row.min_iterations[0] - 1},
            {"solver_ls_iterations": row.min_iterations[1] - 1},
        ):
            with pytest.raises(InputError, match=f"on {feet} feet"):
                check_contact_model(replace(config, **fewer), on_heightfield=on_heightfield)


def test_a_row_put_in_front_wins_and_lifts_a_refusal(monkeypatch):
    """What benchmarks/divergence_history.py does to show what a minimum prevents: a narrower row in
    front of the table is the first match, for its feet only."""
    stance = envs.with_float64_physics(envs.with_contact_model(EnvConfig(feet="aff"), "stance"))
    fewer = replace(stance, solver_iterations=8)
    with pytest.raises(InputError, match="solver_iterations >= 16"):
        check_contact_model(fewer)
    row = resolve("stance", "aff", float64_physics=True, on_heightfield=False)
    monkeypatch.setattr(
        contact_physics, "CONTACT_PHYSICS", (replace(row, feet=("aff",), min_iterations=(8, 16)), *CONTACT_PHYSICS)
    )
    check_contact_model(fewer)
    assert resolve("stance", "aof", float64_physics=True, on_heightfield=False).min_iterations == (16, 16)


def test_an_unknown_contact_model_or_feet_is_refused():
    """Every reader of the table refuses a contact model it does not have, naming the ones it has;
    'stance' has no row for the closed chain (CPU evaluation runs it under 'build')."""
    with pytest.raises(InputError, match="unknown contact model 'soft'") as e:
        resolve("soft", "ball", float64_physics=False, on_heightfield=False)
    assert all(model in e.value.fix for model in ("stance", "fast", "build"))
    for call in (
        lambda: envs.physics("ball", "soft"),
        lambda: envs.default_config("flat", "ball", "B", "soft"),
        lambda: envs.with_contact_model(EnvConfig(feet="ball"), "soft"),
        lambda: check_contact_model(replace(EnvConfig(feet="ball"), contact_model="soft")),
    ):
        with pytest.raises(InputError, match="unknown contact model 'soft'"):
            call()
    with pytest.raises(InputError, match="no physics for full feet"):
        resolve("stance", "full", float64_physics=False, on_heightfield=False)
    assert resolve("build", "full", float64_physics=False, on_heightfield=False).min_iterations == (16, 50)
