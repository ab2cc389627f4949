"""Offscreen rendering of a recorded trajectory: frames, an animated GIF and a frame strip; GIFs
shrunk to the repository's budget (shrink_gif).

MuJoCo chooses its OpenGL backend from the environment variable MUJOCO_GL when `mujoco` is first
imported (egl: headless, GPU or Mesa; osmesa: software; glfw: needs a display; disable: none),
so it must be set before Python starts; footforge's command lines set it to disable where it is
unset (footforge.headless_by_default; importing footforge as a library leaves it alone), and
importing footforge sets it to disable where the library it names is missing, which would
otherwise fail `import mujoco` (footforge.GL_UNAVAILABLE says why).
Frames are RGB uint8 arrays of shape (height, width, 3); the camera is a free camera that follows
the base (qpos[:3], a free joint).
"""

from __future__ import annotations

import copy
import os
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

import footforge
from footforge.atomic import atomic_file
from footforge.errors import InputError

RENDER_FIX = (
    "install an OpenGL backend (e.g. apt install libosmesa6) and set MUJOCO_GL=osmesa (or egl) before starting Python"
)


def _renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    """A renderer of `model` (offscreen buffer raised on a copy when smaller than the image).

    Raises:
      InputError: no OpenGL context could be made, for whatever reason.
    """
    if model.vis.global_.offwidth < width or model.vis.global_.offheight < height:
        model = copy.copy(model)  # the caller's model keeps its visual settings
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    if footforge.GL_SET_BY_FOOTFORGE and os.environ.get("MUJOCO_GL") == "disable":
        raise InputError(
            "rendering needs an OpenGL backend named in MUJOCO_GL, and none is set (footforge's "
            "commands then render nothing)",
            fix="run the command as MUJOCO_GL=egl footforge ... "
            "(a GPU or Mesa's EGL) or MUJOCO_GL=osmesa footforge ... (software: apt install libosmesa6)",
        )
    if footforge.GL_UNAVAILABLE is not None:
        backend, reason = footforge.GL_UNAVAILABLE
        raise InputError(f"MuJoCo cannot render offscreen with MUJOCO_GL={backend}: {reason}", fix=RENDER_FIX)
    try:
        # Imported here, not taken from `mujoco`: `import mujoco` swallows an ImportError of its
        # rendering module (e.g. MUJOCO_GL=osmesa without libOSMesa); importing again raises it.
        from mujoco.rendering.classic import gl_context
        from mujoco.rendering.classic.renderer import Renderer

        if not hasattr(gl_context, "GLContext"):
            raise RuntimeError("rendering is disabled")
        return Renderer(model, height=height, width=width)
    except Exception as e:  # every backend fails its own way: ImportError, FatalError, EGLError...
        backend = os.environ.get("MUJOCO_GL", "")
        raise InputError(f"MuJoCo cannot render offscreen with MUJOCO_GL={backend}: {e}", fix=RENDER_FIX) from None


def check_renderer() -> None:
    """Creates and closes a small renderer, so that a missing backend shows before any heavy work.

    Raises:
      InputError: no OpenGL context could be made.
    """
    _renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 16, 16).close()


def render_frames(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    width: int = 640,
    height: int = 360,
    every: int = 1,
    distance_m: float = 2.0,
    elevation_deg: float = -20.0,
    azimuth_deg: float = 120.0,
) -> list[np.ndarray]:
    """Renders every `every`-th row of `qpos` (T, model.nq), the camera looking at the base.

    Azimuth and elevation are MuJoCo's: the camera looks along (cos az cos el, sin az cos el,
    sin el) from `distance_m` before the base, so azimuth 90 views the robot's right side
    (it walks along +x) and a negative elevation looks down.

    Raises:
      InputError: no OpenGL context could be made.
      ValueError: `qpos` is not (T, model.nq).
    """
    qpos = np.asarray(qpos)
    if qpos.ndim != 2 or qpos.shape[1] != model.nq:
        raise ValueError(f"qpos must be (T, {model.nq}), got {qpos.shape}")
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance, camera.elevation, camera.azimuth = distance_m, elevation_deg, azimuth_deg
    data = mujoco.MjData(model)
    frames = []
    with _renderer(model, width, height) as renderer:
        for q in qpos[::every]:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            camera.lookat[:] = q[:3]
            renderer.update_scene(data, camera=camera)
            frames.append(renderer.render())
    return frames


def write_gif(frames: Sequence[np.ndarray], path: Path, fps: float, comment: str | None = None) -> None:
    """An animated GIF that loops, written whole or not at all. GIF delays are whole 10 ms, and
    Pillow merges identical consecutive frames (their delays add up). `comment` goes into the
    GIF's comment extension (Pillow reads it back as info["comment"], bytes)."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    extra = {"comment": comment} if comment else {}
    with atomic_file(path) as tmp:
        images[0].save(
            tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps), loop=0, **extra
        )


def write_strip(frames: Sequence[np.ndarray], path: Path, count: int = 6) -> None:
    """`count` evenly spaced frames (first and last included; fewer if there are fewer frames)
    side by side in one PNG, written whole or not at all."""
    from PIL import Image

    if not frames:
        raise ValueError("no frames to write")
    picks = np.linspace(0, len(frames) - 1, min(count, len(frames))).round().astype(int)
    strip = Image.fromarray(np.concatenate([frames[i] for i in picks], axis=1))
    with atomic_file(path) as tmp:
        strip.save(tmp, format="PNG")


GIF_MAX_BYTES = 300_000
"""A committed GIF's budget (the repository's size rule): 300 KB, the README's walking GIFs."""
POLICY_GIF_MAX_BYTES = 200_000
"""The budget of the one GIF a policy folder keeps (its evaluation's video_0.gif): 200 KB, 192-224 px
wide for a 3-s clip. Each rough policy adds about 2 MB of weights to the tree, so its record's GIF is
smaller than the README's."""


def shrink_gif(
    path: Path, max_bytes: int = GIF_MAX_BYTES, max_seconds: float = 3.0, max_fps: float = 12.5
) -> tuple[int, int, int]:
    """Rewrites the GIF at `path` in place to fit `max_bytes`: its first `max_seconds` at most
    `max_fps` (every other frame of footforge's 25-fps videos; a GIF already that slow keeps every
    frame, so shrinking twice does not halve it twice), then the largest width (320 px down to
    160 px) and palette (32 or 16 colours, one for the whole clip, no dithering; Pillow's
    maximum-coverage quantiser, which keeps a small object's own colour where median cut merges it
    into the floor) whose file fits. A camera that follows the robot moves the checkered floor in
    every frame, so a GIF's size grows with its frames and pixels and little else helps. Keeps the
    GIF's comment. Returns (width px, colours, bytes).

    Raises:
      ValueError: not even 160 px and 16 colours fit `max_bytes`.
    """
    import io

    from PIL import Image, ImageSequence

    with Image.open(path) as gif:
        comment = gif.info.get("comment")
        frame_ms = gif.info.get("duration", 40)
        every = max(1, round(1000 / max_fps / frame_ms))
        keep = max(1, int(max_seconds * 1000 / (frame_ms * every)))
        frames = [f.convert("RGB") for i, f in enumerate(ImageSequence.Iterator(gif)) if i % every == 0][:keep]
    extra = {"comment": comment} if comment else {}
    for width in (320, 288, 256, 224, 192, 160):
        for colours in (32, 16):
            if width > frames[0].width:
                continue
            sized = [f.resize((width, round(width * f.height / f.width)), Image.Resampling.LANCZOS) for f in frames]
            palette = sized[len(sized) // 2].quantize(colors=colours, method=Image.Quantize.MAXCOVERAGE)
            images = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in sized]
            buffer = io.BytesIO()
            images[0].save(
                buffer,
                format="GIF",
                save_all=True,
                append_images=images[1:],
                duration=frame_ms * every,
                loop=0,
                optimize=True,
                **extra,
            )
            if buffer.tell() <= max_bytes:
                with atomic_file(path) as tmp:
                    Path(tmp).write_bytes(buffer.getvalue())
                return width, colours, buffer.tell()
    raise ValueError(f"{path}: {len(frames)} frames do not fit {max_bytes:,} bytes even at 160 px and 16 colours")
