"""The README's walking GIFs: `footforge play` headless under a straight 0.6 m/s command, then
every second frame (12.5 fps) on one 64-colour palette, so that a 4 s clip stays under 1 MB.

    MUJOCO_GL=egl python scripts/readme_gif.py policies/flat_aof_B docs/images/walk_aof.gif
    MUJOCO_GL=egl python scripts/readme_gif.py policies/flat_aof_B docs/images/walk_aof_closed_chain.gif --feet full
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) not in (2, 4) or len(argv) == 4 and argv[2] != "--feet":
        print(__doc__, file=sys.stderr)
        return 2
    policy, out, feet = argv[0], argv[1], argv[3:]
    from PIL import Image, ImageSequence

    from footforge.cli.play import main as play

    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "raw.gif"
        code = play(
            [
                policy,
                "--headless",
                "--seconds",
                "4",
                "--command",
                "0.6",
                "0",
                "0",
                "--video",
                str(raw),
                "--width",
                "320",
                "--height",
                "180",
                *(["--feet", *feet] if feet else []),
            ]
        )
        if code:
            return code
        with Image.open(raw) as gif:
            frames = [f.convert("RGB") for i, f in enumerate(ImageSequence.Iterator(gif)) if i % 2 == 0]
    palette = frames[len(frames) // 2].quantize(colors=64, method=Image.Quantize.MEDIANCUT)
    frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    frames[0].save(out, save_all=True, append_images=frames[1:], duration=80, loop=0, optimize=True)
    print(f"{out}: {len(frames)} frames, {Path(out).stat().st_size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
