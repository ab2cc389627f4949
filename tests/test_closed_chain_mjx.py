"""The closed chain on MJX (issue 17, item 6): the 34-joint foot, batched, steps stably, keeps its
loops shut and lands where CPU MuJoCo lands it (benchmarks/closed_chain_mjx.py)."""

import json
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from conftest import REPO


def _cpu_reference(rig_path, seconds: float) -> tuple[float, float]:
    """CPU MuJoCo, float64: the slider's height after `seconds` from 2 cm above the reference
    pose, and the largest closure opening (m)."""
    model = mujoco.MjModel.from_xml_path(str(rig_path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("reference").id)
    slider = model.jnt_qposadr[model.joint("slider").id]
    data.qpos[slider] += 0.02
    connects = [e for e in range(model.neq) if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT]
    worst = 0.0
    for _ in range(int(round(seconds / model.opt.timestep))):
        mujoco.mj_step(model, data)
        worst = max(
            worst,
            max(
                np.linalg.norm(data.site_xpos[model.eq_obj1id[e]] - data.site_xpos[model.eq_obj2id[e]])
                for e in connects
            ),
        )
    return float(data.qpos[slider]), worst


@pytest.mark.slow  # compiling the closed chain's MJX step takes about a minute on 2 cores
@pytest.mark.timeout(600)  # explicit budget: several times its time on 2 quiet cores
def test_the_closed_chain_steps_on_mjx_batched_and_stays_closed(built):
    folder = built["full"][0]
    run = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks/closed_chain_mjx.py"),
            "--model",
            "rig",
            "--build",
            str(folder),
            "--batch",
            "4",
            "--seconds",
            "1.0",
        ],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    result = json.loads(run.stdout.strip().splitlines()[-1])
    height, cpu_gap = _cpu_reference(folder / "foot_rig.xml", 1.0)
    assert result["finite"] and result["connect_closures"] == 3, result
    assert result["max_closure_gap_mm"] < 0.5, result  # footforge validate's limit for the reference
    # Landed and settled where CPU MuJoCo (float64) puts it, under the 13 kg payload.
    assert result["slider_height_m"] == pytest.approx(height, abs=1e-3), (result, height)
    assert cpu_gap < 0.5e-3
