"""Offscreen rendering: frames, GIF and strip where an OpenGL backend exists, a clear InputError
where none does. MuJoCo reads MUJOCO_GL once, at import, so each case runs in its own process."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from conftest import REPO

# A red box on a checkered floor; an offscreen buffer smaller than the frames asked for below.
RENDER = """
import json, sys
from footforge.errors import InputError
from footforge.rl.render import render_frames, write_gif, write_strip  # before mujoco, as footforge's tools do
import mujoco, numpy as np

model = mujoco.MjModel.from_xml_string('''<mujoco>
  <visual><global offwidth="64" offheight="48"/></visual>
  <asset><texture name="grid" type="2d" builtin="checker" rgb1=".2 .3 .4" rgb2=".1 .2 .3" width="64" height="64"/>
    <material name="grid" texture="grid" texrepeat="8 8"/></asset>
  <worldbody><light pos="0 0 3" dir="0 0 -1" directional="true"/>
    <geom type="plane" size="5 5 .1" material="grid"/>
    <body pos="0 0 .1"><freejoint/><geom type="box" size=".1 .1 .1" rgba="1 0 0 1"/></body>
  </worldbody></mujoco>''')
qpos = np.tile(model.qpos0, (10, 1))
qpos[:, 0] = np.linspace(0.0, 1.0, 10)  # the box slides along x; the camera follows it
out = sys.argv[1]
try:
    frames = render_frames(model, qpos, width=96, height=64, every=2, distance_m=1.0)
except InputError as e:
    print(json.dumps({"error": str(e)}))
    sys.exit(0)
write_gif(frames, out + "/video.gif", fps=10)
write_strip(frames, out + "/strip.png", count=3)
print(json.dumps({"frames": len(frames), "offwidth": int(model.vis.global_.offwidth)}))
"""


def _run(code: str, mujoco_gl: str, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": mujoco_gl}
    return subprocess.run(
        [sys.executable, "-c", code, *args], env=env, capture_output=True, text=True, timeout=120, cwd=REPO
    )


@pytest.mark.parametrize("backend", ["osmesa", "egl"])
def test_render_writes_gif_and_strip_or_names_the_fix(tmp_path, backend):
    proc = _run(RENDER, backend, str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    if "error" in result:  # a machine without this backend's library: the message says what to install
        assert f"MUJOCO_GL={backend}" in result["error"] and "libosmesa6" in result["error"]
        assert not list(tmp_path.iterdir())
        pytest.skip(
            f"no MUJOCO_GL={backend} library on this machine (its message names the fix, checked): frames not rendered"
        )
    assert result == {"frames": 5, "offwidth": 64}  # every 2nd of 10; the caller's model unchanged
    with Image.open(tmp_path / "video.gif") as gif:
        assert (gif.n_frames, gif.size, gif.info["duration"], gif.info["loop"]) == (5, (96, 64), 100, 0)
    strip = np.asarray(Image.open(tmp_path / "strip.png").convert("RGB")).astype(int)
    assert strip.shape == (64, 3 * 96, 3)
    for frame in np.split(strip, 3, axis=1):
        assert frame.std() > 10  # not one colour
        r, g, b = frame[32, 48]
        assert r > g + 50 and r > b + 50  # the tracked red box is in the middle
    assert sorted(p.name for p in tmp_path.iterdir()) == ["strip.png", "video.gif"]  # no temporary files


def test_disabled_rendering_is_an_input_error():
    code = (
        "from footforge.errors import InputError\nfrom footforge.rl.render import check_renderer\n"
        "try:\n    check_renderer()\nexcept InputError as e:\n    print(e)\n"
    )
    proc = _run(code, "disable")
    assert proc.returncode == 0 and not proc.stderr, proc.stderr
    assert "cannot render offscreen with MUJOCO_GL=disable" in proc.stdout
    assert "fix: install an OpenGL backend" in proc.stdout


def test_evaluate_video_without_renderer_exits_2_before_any_work(tmp_path):
    out = tmp_path / "evaluation"
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "pipelines/evaluate.py"),
            "--policy",
            str(tmp_path / "none"),
            "--video",
            "1",
            "--out",
            str(out),
        ],
        env={**os.environ, "MUJOCO_GL": "disable"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "MUJOCO_GL=disable" in proc.stderr and "Traceback" not in proc.stderr
    assert not out.exists()


def test_video_without_a_backend_named_says_which_variable_to_set(tmp_path):
    """MUJOCO_GL unset: the command turned rendering off itself, so the message says to name a
    backend, not that MUJOCO_GL=disable (a value the user never set) cannot render."""
    out = tmp_path / "evaluation"
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "footforge.cli",
            "evaluate",
            "--policy",
            str(tmp_path / "none"),
            "--video",
            "1",
            "--out",
            str(out),
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "needs an OpenGL backend named in MUJOCO_GL, and none is set" in proc.stderr
    assert "MUJOCO_GL=egl footforge" in proc.stderr and "MUJOCO_GL=disable" not in proc.stderr
    assert not out.exists()


def test_importing_footforge_leaves_mujoco_gl_as_the_user_has_it():
    """A library must not change global state on import: a user's own mujoco.Renderer keeps
    MuJoCo's default backend. footforge's command lines default to MUJOCO_GL=disable (they render
    only where asked); a backend the user named is kept."""
    import subprocess
    import sys

    probe = "import os, {module}; print(os.environ.get('MUJOCO_GL'))"
    unset = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    for module, env, expected in (
        ("footforge", unset, "None"),
        ("footforge.cli.main", unset, "disable"),
        ("footforge.cli.train", unset, "disable"),
        ("footforge.cli.main", {**unset, "MUJOCO_GL": "glfw"}, "glfw"),
    ):
        run = subprocess.run(
            [sys.executable, "-c", probe.format(module=module)], env=env, capture_output=True, text=True, timeout=300
        )
        assert run.returncode == 0 and run.stdout.strip().splitlines()[-1] == expected, (module, run.stdout, run.stderr)


def test_shrink_gif_fits_the_budget_keeps_the_comment_or_leaves_the_file(tmp_path):
    """A followed robot's GIF (the floor moves in every frame: here a checkerboard scrolling under a
    fixed square) shrinks to the budget: its first 3 s at half the frame rate, narrower and fewer
    colours until it fits; the comment kept. A budget no setting meets raises and leaves the file
    as it was."""
    from footforge.rl.render import shrink_gif, write_gif

    yy, xx = np.mgrid[0:180, 0:320]
    frames = []
    for t in range(100):  # 4 s at 25 fps
        shade = (((xx + 7 * t) // 20 + yy // 20) % 2) * 90 + 40 + (xx + yy) // 8  # lit checker, scrolling
        frame = np.stack([shade // 3, shade // 2, shade], axis=-1).astype(np.uint8)
        frame[70:110, 140:180] = (220, 30, 30)
        frames.append(frame)
    path = tmp_path / "walk.gif"
    write_gif(frames, path, fps=25, comment="footforge play")
    before = path.stat().st_size
    width, colours, size = shrink_gif(path, max_bytes=before // 8)
    assert size == path.stat().st_size <= before // 8 and width < 320
    with Image.open(path) as gif:
        assert (gif.n_frames, gif.info["duration"], gif.size) == (37, 80, (width, round(width * 180 / 320)))
        assert gif.info["comment"] == b"footforge play"
        gif.seek(18)
        middle = np.asarray(gif.convert("RGB")).astype(int)
    r, g, b = middle[middle.shape[0] // 2, middle.shape[1] // 2]
    assert r > g + 50 and r > b + 50  # still the red square in the middle
    shrink_gif(path, max_bytes=before // 8)  # already 12.5 fps and 3 s: every frame kept
    with Image.open(path) as gif:
        assert (gif.n_frames, gif.info["duration"]) == (37, 80)
    kept = path.read_bytes()
    with pytest.raises(ValueError, match="do not fit 1,000 bytes"):
        shrink_gif(path, max_bytes=1000)
    assert path.read_bytes() == kept and sorted(p.name for p in tmp_path.iterdir()) == ["walk.gif"]
