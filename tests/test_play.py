"""pipelines/play.py: the committed ball-feet policy run headless through its ONNX graph (a GIF
where an OpenGL backend exists, the logged states always), on its own feet and on the closed
chain; the ONNX file and the policy folder act alike; bad inputs exit 2 before any work."""

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

import footforge
from footforge import envs
from footforge.errors import InputError

from conftest import REPO

POLICY = REPO / "policies/flat_ball_B_cpu/policy"
"""A ball-feet flat B policy, 10.1 M steps of the `cpu` preset on a 2-core CPU under commands of up to 1 m/s: it
walks (policies/README.md)."""
PLAY = str(REPO / "pipelines/play.py")


def _play(*args, mujoco_gl="disable", timeout=300) -> subprocess.CompletedProcess:
    # MuJoCo reads MUJOCO_GL once, at import: every run is a process of its own.
    return subprocess.run(
        [sys.executable, PLAY, *map(str, args)],
        env={**os.environ, "MUJOCO_GL": mujoco_gl},
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
    )


def _backend() -> str | None:
    """An offscreen backend whose library the loader finds (footforge's own test), or None."""
    for backend in ("egl", "osmesa"):
        if footforge._missing_gl_library(backend) is None:
            return backend
    return None


def _states(log) -> dict:
    data = json.loads(log.read_text())
    assert data["tool"] == "footforge play"
    return data


def test_headless_ball_policy_stands_and_is_filmed(built, tmp_path):
    """1 s at 50 Hz standing still: 50 logged steps, 25 GIF frames (25 fps) of the asked size, the
    base in the band a standing ANYmal C holds (0.52 m nominal), no fall, not drifting away."""
    video, log = tmp_path / "stand.gif", tmp_path / "stand.json"
    backend = _backend()
    video_args = ["--video", video, "--width", 96, "--height", 64] if backend else []
    proc = _play(
        POLICY,
        "--headless",
        "--seconds",
        1,
        "--build-root",
        built["ball"][0].parent,
        "--log",
        log,
        *video_args,
        mujoco_gl=backend or "disable",
    )
    assert proc.returncode == 0, proc.stderr
    data = _states(log)
    assert (data["feet"], data["trained_on"], data["steps"], data["falls"]) == ("ball", "ball", 50, 0)
    assert data["physics_steps_per_policy_step"] == 4
    states = data["states"]
    heights, positions = np.array(states["base_height_m"]), np.array(states["base_pos_m"])
    assert len(heights) == 50 and np.isfinite(heights).all()
    assert 0.40 < heights.min() and heights.max() < 0.62, heights  # upright, not fallen nor jumping
    assert np.linalg.norm(positions[-1, :2]) < 0.6  # a standing policy under a zero command stays near
    assert not any(states["fell"])
    assert "real-time factor" in proc.stdout
    if backend is None:  # no library: the run without --video above still checked the physics
        proc = _play(POLICY, "--headless", "--seconds", 1, "--video", video, mujoco_gl="egl")
        assert proc.returncode == 2 and "cannot render offscreen" in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr and not video.exists()
        return
    with Image.open(video) as gif:
        assert (gif.format, gif.n_frames, gif.size) == ("GIF", 25, (96, 64))
        assert gif.info["duration"] == 40 and gif.info["comment"] == b"footforge play"
        gif.seek(12)
        frame = np.asarray(gif.convert("RGB")).astype(int)
    assert frame.std() > 10  # a picture, not one colour
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stand.gif", "stand.json"]  # no temporary files
    # play replaces what it wrote; a file it did not write needs --force (checked before any work).
    other = tmp_path / "mine.gif"
    other.write_bytes(b"GIF89a user's")
    proc = _play(POLICY, "--headless", "--video", other, mujoco_gl=backend)
    assert proc.returncode == 2 and "not written by footforge play" in proc.stderr and "--force" in proc.stderr
    assert other.read_bytes() == b"GIF89a user's"


def test_headless_ball_policy_walks_forward_by_the_verdict(built, tmp_path):
    """A real rollout judged (footforge.rl.verdict): the shipped ball policy under a 0.6 m/s forward
    command for 4 s in CPU MuJoCo moves forward at about that speed, every foot stepping, and play
    says so in one line and in its log."""
    log = tmp_path / "walk.json"
    proc = _play(
        POLICY,
        "--headless",
        "--seconds",
        4,
        "--command",
        0.6,
        0,
        0,
        "--build-root",
        built["ball"][0].parent,
        "--log",
        log,
    )
    assert proc.returncode == 0, proc.stderr
    walking = _states(log)["walking"]
    assert walking["verdict"] == "walks", walking
    assert f"footforge play: verdict: {walking['line']}" in proc.stdout and walking["line"].startswith("walks: ")
    assert walking["forward_error_mps"] < 0.25 and walking["uptime"] == 1.0
    assert all(0.2 <= f <= 0.9 for f in walking["stance_fraction"].values()), walking["stance_fraction"]
    vx = np.array(_states(log)["states"]["vx"])[50:]  # after the first second
    assert 0.4 < vx.mean() < 0.8


def test_headless_on_the_closed_chain(built, tmp_path):
    """The ball policy on the 34-joint closed chain at its build's 0.25 ms (80 physics steps per
    policy step) through the same runner: finite and standing for half a second."""
    log = tmp_path / "full.json"
    proc = _play(
        POLICY, "--headless", "--feet", "full", "--seconds", 0.5, "--build-root", built["full"][0].parent, "--log", log
    )
    assert proc.returncode == 0, proc.stderr
    data = _states(log)
    assert (data["feet"], data["trained_on"], data["steps"]) == ("full", "ball", 25)
    assert data["physics_steps_per_policy_step"] == 80
    heights = np.array(data["states"]["base_height_m"])
    assert data["falls"] == 0 and np.isfinite(heights).all()
    assert 0.40 < heights.min() and heights.max() < 0.62, heights


def test_onnx_file_and_policy_folder_act_alike(tmp_path):
    """An exported .onnx file gives the policy folder's configuration where it matters and the
    same actions; the key map changes the command as printed."""
    from footforge.rl.export_onnx import export
    from footforge.rl.play import apply_key, key_map_text, load_policy
    from footforge.rl.train import load_policy_config

    folder = load_policy(POLICY)
    onnx_file = load_policy(export(POLICY, tmp_path / "policy.onnx"))
    saved = load_policy_config(POLICY)
    for config in (folder.config, onnx_file.config):
        for field in (
            "task",
            "feet",
            "policy",
            "action",
            "action_scale",
            "action_clip",
            "sim_dt",
            "decimation",
            "observations",
            "height_scan",
        ):
            assert getattr(config, field) == getattr(saved, field), field
    obs = np.random.default_rng(0).normal(size=(3, folder.metadata["observation"]["size"])).astype(np.float32)
    np.testing.assert_array_equal(folder.actions(obs), onnx_file.actions(obs))

    command = np.zeros(3)
    for key in (265, 265, 266, 262):  # Up, Up, Page Up, Right
        command, reset = apply_key(command, key)
        assert not reset
    np.testing.assert_allclose(command, [0.2, 0.1, -0.1])
    assert apply_key(command, 269)[0].tolist() == [0.0, 0.0, 0.0]  # End: stop
    assert apply_key(command, 268)[1]  # Home: back to the start
    assert apply_key(command, 65)[0] is command  # any other key: nothing
    assert "Page Up" in key_map_text() and "yaw rate" in key_map_text()


def test_haptic_policies_keep_their_own_feet_or_the_closed_chain():
    """A BH policy of AOF walks on AOF, or on the closed chain through its sensors' estimates
    (footforge.rl.foot_imu); AFF's passive joints are not AOF's."""
    from footforge.rl.play import OnnxPolicy, check_feet

    bh = OnnxPolicy(POLICY, None, {}, replace(envs.default_config("flat", "aof", "BH")))
    assert check_feet(bh, None) == "aof"
    assert check_feet(bh, "full") == "full"
    with pytest.raises(InputError, match="passive joints") as error:
        check_feet(bh, "aff")
    assert "blind (B) or perceptive (P)" in error.value.fix
    b = OnnxPolicy(POLICY, None, {}, envs.default_config("flat", "ball", "B"))
    assert check_feet(b, "aof") == "aof"


@pytest.mark.parametrize(
    "case, expected",
    [
        ("missing", "no such policy folder or file"),
        ("plain folder", "not a footforge policy (no footforge.json)"),
        ("text file", "neither a policy folder nor an .onnx file"),
        ("broken onnx", "cannot be read as ONNX"),
        ("unknown feet", "unknown feet 'claws'"),
        ("mp4", "play writes an animated GIF only"),
        ("no folder", "does not exist"),
        ("video without headless", "--video and --log are for --headless runs"),
        ("no display", "no display for MuJoCo's viewer"),
        ("bad seconds", "--seconds must be positive"),
    ],
)
def test_bad_inputs_exit_2_with_a_message(tmp_path, case, expected):
    (tmp_path / "folder").mkdir()
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "broken.onnx").write_bytes(b"\x00not protobuf\xff" * 10)
    args = {
        "missing": [tmp_path / "none", "--headless"],
        "plain folder": [tmp_path / "folder", "--headless"],
        "text file": [tmp_path / "notes.txt", "--headless"],
        "broken onnx": [tmp_path / "broken.onnx", "--headless"],
        "unknown feet": [POLICY, "--headless", "--feet", "claws"],
        "mp4": [POLICY, "--headless", "--video", tmp_path / "walk.mp4"],
        "no folder": [POLICY, "--headless", "--video", tmp_path / "none/walk.gif"],
        "video without headless": [POLICY, "--video", tmp_path / "walk.gif"],
        "no display": [POLICY],
        "bad seconds": [POLICY, "--headless", "--seconds", 0],
    }[case]
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run(
        [sys.executable, PLAY, *map(str, args)],
        env={**env, "MUJOCO_GL": "disable"},
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert proc.returncode == 2, proc.stderr
    assert expected in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("footforge play: error: ")
    assert not (tmp_path / "walk.gif").exists() and not (tmp_path / "walk.mp4").exists()


def test_viewer_loop_takes_keys_and_steps(built, monkeypatch):
    """The interactive loop with a stand-in for MuJoCo's passive viewer (no display here): keys
    pressed change the command within the training ranges, Home restarts, every frame is a
    policy step under the viewer's lock, and the camera follows the base."""
    import mujoco
    import mujoco.viewer

    from footforge.rl.play import PlayConfig, Player, load_policy, play_interactive

    player = Player(load_policy(POLICY), PlayConfig(build_root=built["ball"][0].parent))
    seen = []

    class Viewer:
        def __init__(self, model, data, key_callback):
            assert model is player.model and data is player.data
            self.cam, self.frames, self.locked = mujoco.MjvCamera(), 0, 0
            for key in [265] * 25 + [263, 268]:  # Up 25 times: 2.5 m/s, beyond the trained range; Left; Home
                key_callback(key)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def lock(self):
            viewer = self

            class Lock:
                def __enter__(self):
                    viewer.locked += 1

                def __exit__(self, *exc):
                    return False

            return Lock()

        def is_running(self):
            return self.frames < 5

        def sync(self):
            seen.append(player.data.qpos[:3].copy())
            self.frames += 1

    monkeypatch.setattr(mujoco.viewer, "launch_passive", Viewer)
    printed = []
    play_interactive(player, print_fn=printed.append)
    assert len(seen) == 5 and np.isfinite(seen).all()
    top = player.policy.config.commands.lin_vel_x_range[1]  # clipped to the training range (1 m/s)
    assert top < 2.5 and printed[-1] == f"command: vx {top:+.1f} m/s, vy +0.0 m/s, yaw rate +0.1 rad/s"
    assert len(printed) == 27 and player.resets == 3  # the start, after the warm-up, then Home
