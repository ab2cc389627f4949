"""The offline GPU kit (scripts/device): usage errors, the results tarball round trip, and (slow)
the CPU dry run that mimics the GPU machine end to end."""

import json
import os
import subprocess
import sys
import tarfile

import pytest

from footforge.rl.train import write_checkpoint_manifest

from conftest import REPO

sys.path.insert(0, str(REPO / "scripts/device"))
import kit  # noqa: E402


def test_run_sh_without_a_kit_is_a_usage_error(tmp_path):
    done = subprocess.run(
        [str(REPO / "scripts/device/run.sh"), "--kit", str(tmp_path / "none"), "bench"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2 and "prepare.sh" in done.stderr


def test_prepare_and_dryrun_refuse_extra_arguments():
    for script in ("prepare.sh", "dryrun.sh"):
        done = subprocess.run(
            [str(REPO / "scripts/device" / script), "a", "b"], capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 2 and "usage" in done.stderr


def test_results_tarball_keeps_the_latest_checkpoint_and_unpacks(tmp_path):
    run = tmp_path / "runs" / "flat_ball_B"
    for step in (32, 64):
        (run / "checkpoints" / f"{step:012d}").mkdir(parents=True)
        (run / "checkpoints" / f"{step:012d}" / "params").write_text(str(step))
        write_checkpoint_manifest(run / "checkpoints" / f"{step:012d}")
    (run / "checkpoints" / "000000000016.corrupt").mkdir()
    (run / "policy").mkdir()
    (run / "progress.json").write_text(json.dumps({"global_step": 64, "num_timesteps": 64}))
    results = tmp_path / "results"
    results.mkdir()
    name = kit.pack(run, results)
    with tarfile.open(results / name) as tar:
        names = set(tar.getnames())
    assert "flat_ball_B/checkpoints/000000000064/params" in names
    assert not any("000000000032" in n or ".corrupt" in n for n in names)
    # the newest damaged after its write: the pack falls back to the newest intact one
    (run / "checkpoints" / "000000000064" / "params").write_text("6")
    with tarfile.open(results / kit.pack(run, results)) as tar:
        names = set(tar.getnames())
    assert "flat_ball_B/checkpoints/000000000032/params" in names
    assert not any("000000000064" in n for n in names)
    (run / "checkpoints" / "000000000064" / "params").write_text("64")
    kit.pack(run, results)
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    kit.unpack(results / name, fresh)
    assert kit.run_state(fresh / "flat_ball_B") | {"metrics": {}} == {
        "global_step": 64,
        "num_timesteps": 64,
        "complete": True,
        "stopped": None,
        "metrics": {},
    }
    with pytest.raises(kit.UsageError):
        kit.unpack(tmp_path / "missing.tar.gz", fresh)


@pytest.mark.device_kit
@pytest.mark.timeout(3600)  # installs a JAX stack from the package index: 20-25 minutes
def test_cpu_dry_run_of_the_gpu_kit(tmp_path):
    """scripts/device/dryrun.sh: JAX 0.11.2 venv + the kit's wheels, train, resume, evaluate.
    Needs a package index and Python 3.12; 17-25 minutes on 2 busy cores (mostly installing and
    compiling). Run before a GPU campaign (`python -m pytest -m device_kit`, or dryrun.sh itself);
    CI leaves it out (pyproject's markers)."""
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    env.setdefault("PREPARE_PYTHON", sys.executable)
    done = subprocess.run(
        [str(REPO / "scripts/device/dryrun.sh"), str(tmp_path / "dry")],
        capture_output=True,
        text=True,
        env=env,
        timeout=3600,
    )
    last = json.loads(done.stdout.strip().splitlines()[-1])
    assert done.returncode == 0 and last["dryrun"] == "ok", done.stdout[-4000:] + done.stderr[-2000:]


def test_campaign_takes_a_spec_that_begins_with_an_option_and_refuses_an_unknown_option(tmp_path):
    """A SPEC may begin with run.sh's --resume (the campaign of 2026-11-24 was refused so); a
    misspelt campaign option is still a usage error."""
    campaign = str(REPO / "scripts/device/campaign.sh")
    common = ["--kit", str(tmp_path / "none"), "--results", str(tmp_path / "out")]
    done = subprocess.run(
        [campaign, *common, "--resume x.tar.gz train-flat ball B"], capture_output=True, text=True, timeout=120
    )
    assert "unknown option" not in done.stderr
    assert done.returncode == 1 and "the kit did not install" in done.stderr  # it went on to the kit
    done = subprocess.run([campaign, "--minute", "5", "train-flat ball B"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "unknown option --minute" in done.stderr


def test_cpu_jobs_get_disjoint_equal_shares_of_the_cores():
    """campaign.sh --cpu pins job i of n to kit.core_share(cores, n, i): together every core once, sizes
    within one of each other, consecutive; more jobs than cores share them in turn."""
    for cpus in (list(range(16)), [0, 2, 4, 6, 8, 10, 12], [3]):
        for jobs in range(1, len(cpus) + 1):
            shares = [kit.core_share(cpus, jobs, i) for i in range(jobs)]
            assert sorted(c for share in shares for c in share) == cpus, (cpus, jobs)
            assert max(map(len, shares)) - min(map(len, shares)) <= 1
            assert all(share == cpus[cpus.index(share[0]) : cpus.index(share[0]) + len(share)] for share in shares)
    assert [kit.core_share([0, 1], 3, i) for i in range(3)] == [[0], [1], [0]]
    done = subprocess.run(
        [sys.executable, str(REPO / "scripts/device/kit.py"), "--core-share", "1", "0"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.stdout.strip() == ",".join(map(str, sorted(os.sched_getaffinity(0))))


def test_campaign_takes_cpu_and_leaves_no_temporary_folder(tmp_path):
    campaign = str(REPO / "scripts/device/campaign.sh")
    common = ["--kit", str(tmp_path / "none"), "--results", str(tmp_path / "out"), "--cpu"]
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    done = subprocess.run(
        [campaign, *common, "train-rough aof P"],
        capture_output=True,
        text=True,
        timeout=120,
        env=os.environ | {"TMPDIR": str(temporary)},
    )
    assert "unknown option" not in done.stderr
    assert done.returncode == 1 and "the kit did not install" in done.stderr  # it went on to the kit
    assert list(temporary.iterdir()) == []
