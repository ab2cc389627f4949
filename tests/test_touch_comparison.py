"""benchmarks/touch_comparison.py: the level each run reached, where it plateaued, and the touch answer
the seeds give, on constructed curves whose answers are known."""

from __future__ import annotations

import gzip
import importlib.util
import json

import numpy as np

from conftest import REPO

spec = importlib.util.spec_from_file_location("touch_comparison", REPO / "benchmarks/touch_comparison.py")
touch = importlib.util.module_from_spec(spec)
spec.loader.exec_module(touch)

STEP = 250_000


def _run(folder, policy, seed, levels, gzipped=False, evaluation=None):
    """A kept rough run whose curve logs `levels` every STEP steps (and a row of another kind between)."""
    folder.mkdir(parents=True)
    (folder / "config.json").write_text(
        json.dumps({"env": {"task": "rough", "feet": "aof", "policy": policy}, "ppo": {"seed": seed}})
    )
    rows = []
    for i, level in enumerate(levels, start=1):
        rows += [{"global_step": i * STEP, touch.LEVEL_KEY: level}, {"global_step": i * STEP, "eval/x": 0.0}]
    rows.append({"global_step": 2 * STEP, touch.LEVEL_KEY: float("nan")})  # a non-finite log: left out
    text = "".join(json.dumps(r) + "\n" for r in rows) + '{"global_step": 9'  # a line cut by a kill
    if gzipped:
        (folder / "metrics.jsonl.gz").write_bytes(gzip.compress(text.encode()))
    else:
        (folder / "metrics.jsonl").write_text(text)
    if evaluation is not None:
        (folder / "evaluation").mkdir()
        (folder / "evaluation" / "metrics.json").write_text(json.dumps([evaluation]))


def _ramp(top, steps=80):
    """Rises linearly to `top` over the first 40 logs (10 M steps), then stays there."""
    return [top * min(1.0, i / 40) for i in range(1, steps + 1)]


def test_the_level_reached_is_the_last_window_and_the_plateau_where_it_came_within_tolerance():
    rows = [{"global_step": (i + 1) * STEP, touch.LEVEL_KEY: v} for i, v in enumerate(_ramp(4.0))]
    found = touch.level_reached(rows)
    assert found["steps"] == 80 * STEP and found["level"] == 4.0
    # The trailing 3-M window ending at log k holds logs k-11..k; the plateau starts at the first log whose
    # window mean is within the tolerance of 4.0, found here from the ramp's values by another loop.
    values = _ramp(4.0)
    first = next(k for k in range(12, 81) if 4.0 - sum(values[k - 12 : k]) / 12 <= touch.PLATEAU_TOLERANCE_LEVELS)
    assert found["plateau_from_step"] == first * STEP and 40 * STEP < first * STEP < 50 * STEP


def test_the_trailing_means_at_once_are_each_window_mean():
    """The prefix-sum means (level_reached's plateau search) against the direct mean of each window, on
    uneven logs with two rows at one step."""
    rng = np.random.default_rng(3)
    steps = np.cumsum(rng.choice([0, 250_000, 2_000_000], 200))  # zeros: repeated steps; 2 M: a sparse stretch
    rows = [{"global_step": int(s), touch.LEVEL_KEY: float(v)} for s, v in zip(steps, rng.uniform(0, 9, 200))]
    rows.sort(key=lambda r: r["global_step"])
    assert len({r["global_step"] for r in rows}) < len(rows)
    direct = [touch._window_mean(rows, r["global_step"]) for r in rows]
    np.testing.assert_allclose(touch._trailing_means(rows), direct, rtol=0, atol=1e-9)


def test_touch_helps_only_beyond_the_spread_of_the_seeds(tmp_path, capsys):
    """Three seeds per arm: PH reaches 4 +- 0.1, P 2 +- 0.1 (touch helps); a second comparison whose arms
    overlap (3.0-3.3 against 3.1-3.2) is no difference; one seed per arm is no answer."""
    for seed, top in enumerate((3.9, 4.0, 4.1)):
        _run(tmp_path / f"ph{seed}", "PH", seed, _ramp(top), gzipped=seed == 0)
    for seed, top in enumerate((1.9, 2.0, 2.1)):
        _run(tmp_path / f"p{seed}", "P", seed, _ramp(top, steps=60))  # shorter: the common step is 60 logs
    assert (
        touch.main([*(str(tmp_path / f"{a}{s}") for a in ("ph", "p") for s in range(3)), "--out", str(tmp_path / "o")])
        == 0
    )
    out = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert out["common_step"] == 60 * STEP
    assert out["arms"]["aof_PH"]["level"] == {"mean": 4.0, "sd": 0.1, "n": 3}
    assert out["arms"]["aof_P"]["level_at_common_step"]["mean"] == 2.0
    assert any("level: +2.000, beyond" in a and "touch helps" in a for a in out["answers"]), out["answers"]
    assert (tmp_path / "o" / "touch_comparison.png").stat().st_size > 0
    assert "| aof_PH | 3 | 4.000 ± 0.100 |" in (tmp_path / "o" / "touch_comparison.md").read_text()

    # BH 3.0 and 3.4 (mean 3.2, sd 0.283), B 3.0 and 3.1 (mean 3.05, sd 0.071): the gap of 0.15 is more than
    # B's spread alone and less than the two added.
    for seed, top in enumerate((3.0, 3.4)):
        _run(tmp_path / f"bh{seed}", "BH", seed, _ramp(top))
    for seed, top in enumerate((3.0, 3.1)):
        _run(tmp_path / f"b{seed}", "B", seed, _ramp(top))
    assert touch.main([str(tmp_path / n) for n in ("bh0", "bh1", "b0", "b1")] + ["--out", str(tmp_path / "o2")]) == 0
    answers = json.loads(capsys.readouterr().out.splitlines()[-1])["answers"]
    assert any(a.startswith("AOF BH vs B, level: +0.150, no difference beyond") for a in answers), answers

    assert touch.main([str(tmp_path / "ph0"), str(tmp_path / "p0"), "--out", str(tmp_path / "o3")]) == 0
    answers = json.loads(capsys.readouterr().out.splitlines()[-1])["answers"]
    assert answers[0] == "AOF PH vs P, level: one seed in an arm, no spread to judge by: no answer yet"


def test_evaluations_give_the_shares_fell_and_crossed(tmp_path, capsys):
    evaluation = {
        "task": "rough",
        "feet": "aof",
        "num_envs": 200,
        "seconds": 17.5,
        "falls": 50,
        "crossed": 120,
        "indices": {"lin_vel_x_error": {"mean": 0.2}},
        "walking": {"verdict": "falls"},
    }
    _run(tmp_path / "p", "P", 0, _ramp(2.0), evaluation=evaluation)
    assert touch.main([str(tmp_path / "p"), "--out", str(tmp_path / "o")]) == 0
    run = json.loads(capsys.readouterr().out.splitlines()[-1])["runs"]["p"]
    assert run["evaluation"] == {
        "robots": 200,
        "seconds": 17.5,
        "fell": 0.25,
        "crossed": 0.6,
        "vx_error_mps": 0.2,
        "verdict": "falls",
    }
    older = {k: v for k, v in evaluation.items() if k != "crossed"}  # from before crossings were counted
    _run(tmp_path / "p1", "P", 1, _ramp(2.0), evaluation=older)
    assert touch.main([str(tmp_path / "p"), str(tmp_path / "p1"), "--out", str(tmp_path / "o1")]) == 0
    out = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert out["runs"]["p1"]["evaluation"]["crossed"] is None and "crossed" not in out["arms"]["aof_P"]
    assert out["arms"]["aof_P"]["fell"] == {"mean": 0.25, "sd": 0.0, "n": 2}


def test_a_run_given_twice_and_a_run_without_levels_are_refused(tmp_path, capsys):
    _run(tmp_path / "p", "P", 0, _ramp(2.0))
    (tmp_path / "again").mkdir()
    for name in ("config.json", "metrics.jsonl"):
        (tmp_path / "again" / name).write_bytes((tmp_path / "p" / name).read_bytes())
    assert touch.main([str(tmp_path / "p"), str(tmp_path / "again"), "--out", str(tmp_path / "o")]) == 2
    assert "each seed counts once" in capsys.readouterr().err
    _run(tmp_path / "young", "PH", 0, [])
    assert touch.main([str(tmp_path / "young"), "--out", str(tmp_path / "o")]) == 2
    assert "no episode/terrain/level_per_step rows yet" in capsys.readouterr().err


def test_a_flat_run_is_refused(tmp_path, capsys):
    (tmp_path / "f").mkdir()
    (tmp_path / "f" / "config.json").write_text(json.dumps({"env": {"task": "flat"}, "ppo": {"seed": 0}}))
    assert touch.main([str(tmp_path / "f"), "--out", str(tmp_path / "o")]) == 2
    assert "takes rough runs" in capsys.readouterr().err
