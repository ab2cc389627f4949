#!/usr/bin/env bash
# Prepare the offline GPU kit, here (a machine with the pinned footforge environment and a package index).
#
#   scripts/device/prepare.sh [KITDIR]        # default: .kit/ at the repository root (ignored by git)
#
# Writes KITDIR/build/{ball,aff,aof}/ (MJCF models: the GPU machine has no dm_control, pin, coacd
# or usd-core to build them) and KITDIR/wheels/ (mujoco, mujoco-mjx, brax and the pure-Python
# packages the training path imports that the GPU machine lacks; never jax, jaxlib, flax, optax,
# orbax, numpy or scipy: the machine's own are used), then checks the kit is under 60 MiB.
# Environment: PYTHON (default python3: the pinned footforge environment that builds the models),
# FOOTFORGE (default: "$PYTHON -m footforge.cli"), KIT_MAX_MIB (default 60).
# Exit codes: 0 kit ready, 1 a step or the size check failed, 2 usage error.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
if [[ $# -gt 1 || "${1:-}" == -* ]]; then
    echo "usage: $0 [KITDIR]   (default $repo/.kit)" >&2
    exit 2
fi
kit="${1:-$repo/.kit}"
python="${PYTHON:-python3}"
footforge="${FOOTFORGE:-$python -m footforge.cli}"
max_mib="${KIT_MAX_MIB:-60}"
fail() { echo "prepare: error: $*" >&2; exit 1; }

# The wheels the GPU machine lacks (Python 3.12, x86-64 Linux). Each one's Requires-Dist was
# checked against the machine's packages (docs/training.md, "Training on an offline GPU machine").
WHEELS=(
    mujoco==3.17.0 mujoco-mjx==3.17.0 brax==0.14.2
    tensorboardX==2.6.5   # footforge.rl.train's logger (the machine has tensorboard, not tensorboardX)
    ml_collections==1.1.0 # imported by brax.training.agents.ppo.checkpoint
    jaxopt==0.8.5         # imported by brax.envs (brax.generalized.constraint)
    trimesh==5.2.0        # imported by mujoco.mjx at import time (mjx/_src/mesh.py)
)
# Not carried although listed in their Requires-Dist, because the training path never imports
# them: flask, flask-cors, jinja2 (brax's visualiser), glfw, pyopengl, websockets (mujoco's viewer
# and rendering: MUJOCO_GL is "disable" under footforge), dm-env. The dry run
# (scripts/device/dryrun.sh) checks that the training path runs with exactly this set.

mkdir -p "$kit/build" "$kit/wheels"
for feet in ball aff aof; do
    if [[ -f "$kit/build/$feet/scene.xml" && -z "${REBUILD:-}" ]]; then
        echo "prepare: build/$feet exists (REBUILD=1 to rebuild)"
        continue
    fi
    echo "prepare: building $feet"
    rm -rf "$kit/build/$feet"
    (cd "$repo" && $footforge build --variant "$feet" --format mjcf --out "$kit/build/$feet") >"$kit/build_$feet.log" 2>&1 \
        || { tail -20 "$kit/build_$feet.log" >&2; fail "footforge build --variant $feet failed (log: $kit/build_$feet.log)"; }
    rm -f "$kit/build_$feet.log"
done

echo "prepare: downloading wheels into $kit/wheels"
"$python" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 --platform manylinux1_x86_64 -d "$kit/wheels" "${WHEELS[@]}" \
    || fail "pip download failed (needs a package index here)"
# Only the wheels named above: an older kit's leftovers would make two versions of one package.
"$python" - "$kit/wheels" "${WHEELS[@]}" <<'PY' || fail "unexpected wheels in the kit"
import re, sys
from pathlib import Path
folder, specs = Path(sys.argv[1]), sys.argv[2:]
want = {re.sub(r"[-_.]+", "_", s.split("==")[0]).lower(): s.split("==")[1] for s in specs}
for w in sorted(folder.glob("*.whl")):
    name, version = w.name.split("-")[:2]
    if want.get(re.sub(r"[-_.]+", "_", name).lower()) != version:
        print(f"prepare: removing {w.name} (not in the kit's list)")
        w.unlink()
missing = set(want) - {re.sub(r"[-_.]+", "_", w.name.split("-")[0]).lower() for w in folder.glob("*.whl")}
if missing:
    sys.exit(f"prepare: error: no wheel for {', '.join(sorted(missing))}")
PY
printf '%s\n' "${WHEELS[@]%%#*}" > "$kit/wheels/REQUIREMENTS.txt"

kib=$(du -sk "$kit" | cut -f1)
mib=$(( (kib + 1023) / 1024 ))
echo "prepare: kit $kit: $mib MiB (limit $max_mib MiB)"
du -sh "$kit"/build/* "$kit"/wheels/*.whl | sed 's/^/  /'
if (( kib > max_mib * 1024 )); then
    fail "the kit is $mib MiB, over the $max_mib MiB limit"
fi
echo "prepare: ok"
