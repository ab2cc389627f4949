#!/usr/bin/env bash
# CPU dry run of the offline GPU kit: mimics the GPU machine and runs a short train-flat job end to end.
#
#   scripts/device/dryrun.sh [WORKDIR] [--rough]      # WORKDIR default: a new folder under /tmp
#
# 1. a fresh Python 3.12 venv in WORKDIR/venv holding only JAX 0.11.2 (CPU) and the packages the
#    GPU machine has (flax, optax, orbax-checkpoint, numpy, scipy, matplotlib, tensorboard, onnx,
#    onnxruntime, rich, pyyaml) from the package index (reused when WORKDIR/venv is complete);
# 2. the kit (KIT, default .kit; made by prepare.sh with PREPARE_PYTHON when missing) and a copy
#    of the repository's tracked and untracked-not-ignored files (what the device tool sends) in
#    WORKDIR/repo;
# 3. there, scripts/device/run.sh exactly as on the machine (wheels installed with pip --target):
#    train-flat ball (tiny: 8 robots, 64 steps, checkpoints every 32), then a fresh runs/ resumed
#    from the results tarball to 128 steps, then evaluate; checks each summary, the tarballs and
#    that no build-time package (dm_control, pinocchio, coacd, pxr, xacro) was imported.
#    With --rough, instead: the prepared rough call (docs/training.md) through campaign.sh --cpu,
#    shortened: its two jobs (dryrun.py's ROUGH_JOBS: AOF B and BH begun under the rough `cpu`
#    preset) for two PPO iterations, then both resumed from their tarballs on a fresh runs/ for one more.
# Environment: PYTHON312 (default: python3.12 on PATH, else pyenv's 3.12), KIT, PREPARE_PYTHON.
# Exit codes: 0 all worked, 1 a step failed, 2 usage error. The last line is a JSON summary.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
args=()
for a in "$@"; do
    case "$a" in
        --rough) ;;
        -*) echo "usage: $0 [WORKDIR] [--rough]" >&2; exit 2 ;;
        *) args+=("$a") ;;
    esac
done
if [[ ${#args[@]} -gt 1 ]]; then
    echo "usage: $0 [WORKDIR] [--rough]" >&2
    exit 2
fi
py=""
for candidate in ${PYTHON312:-} python3.12 "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.12.*/bin/python3; do
    if "$candidate" -c 'import sys; assert sys.version_info[:2] == (3, 12)' 2>/dev/null; then py="$candidate"; break; fi
done
if [[ -z "$py" ]]; then
    echo "dryrun: error: no Python 3.12 found (set PYTHON312)" >&2
    exit 2
fi
exec "$py" "$here/dryrun.py" "$@"
