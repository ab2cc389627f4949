"""The README's walking GIFs: `footforge play` headless under a straight 0.6 m/s command, then
shrunk as the repository keeps GIFs (footforge.rl.render.shrink_gif: 3 s at 12.5 fps, within 300 KB).

    MUJOCO_GL=egl python scripts/readme_gif.py policies/flat_aof_B docs/images/walk_aof.gif
    MUJOCO_GL=egl python scripts/readme_gif.py policies/flat_aof_B docs/images/walk_aof_closed_chain.gif --feet full
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) not in (2, 4) or len(argv) == 4 and argv[2] != "--feet":
        print(__doc__, file=sys.stderr)
        return 2
    policy, out, feet = argv[0], argv[1], argv[3:]
    from footforge.cli.play import main as play
    from footforge.rl.render import shrink_gif

    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "raw.gif"
        code = play(
            [
                policy,
                "--headless",
                "--seconds",
                "3",
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
        width, colours, size = shrink_gif(raw)
        shutil.copyfile(raw, out)
    print(f"{out}: {width} px, {colours} colours, {size / 1e3:.0f} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
