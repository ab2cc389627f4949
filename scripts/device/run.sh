#!/usr/bin/env bash
# Entry point on the offline GPU machine (or any machine with JAX but without the footforge stack).
#
#   scripts/device/run.sh [--kit DIR] [--results DIR] [--minutes M] [--resume RESULTS.tar.gz|RUNDIR] JOB [ARGS] [-- EXTRA]
#
# JOB: bench [FEET...] | train-flat FEET [POLICY] | train-rough FEET POLICY | evaluate RUN [FEET...]
# (scripts/device/kit.py --help says more). Installs the kit's wheels (KIT/wheels, made by
# prepare.sh) with pip --no-index --no-deps --target $KIT_SITE (default /tmp/site), puts that and
# the repository on PYTHONPATH, sets the XLA options below (values already in the environment
# win), and runs the job with the machine's own JAX. Nothing is downloaded.
# Environment: PYTHON (default python3), KIT_SITE (default /tmp/site).
# Exit codes: 0 job done (a training stopped at its time budget is done: --resume continues),
# 1 install or job failed, 2 usage error.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
python="${PYTHON:-python3}"
site="${KIT_SITE:-/tmp/site}"
kit="$repo/.kit"
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do  # --kit is needed here, before Python; kit.py reads the rest
    if [[ "${args[i]}" == "--kit" && $((i + 1)) -lt ${#args[@]} ]]; then kit="${args[i+1]}"; fi
    if [[ "${args[i]}" == "--" ]]; then break; fi
done
if [[ ! -d "$kit/wheels" ]]; then
    echo "run: error: no wheels in $kit/wheels: run scripts/device/prepare.sh where a package index is reachable, and bring $kit" >&2
    exit 2
fi

# Install once per machine (a stamp records which wheels are in $site).
stamp="$site/.footforge-kit"
wanted="$(cd "$kit/wheels" && ls -1 *.whl | sort)"
if [[ ! -f "$stamp" || "$(cat "$stamp")" != "$wanted" ]]; then
    if [[ -e "$site" && ! -f "$stamp" && -n "$(ls -A "$site" 2>/dev/null)" ]]; then  # never delete what the kit did not write
        echo "run: error: $site exists and was not made by the kit: set KIT_SITE to a new or empty folder" >&2
        exit 2
    fi
    echo "run: installing $(echo "$wanted" | wc -l) wheels into $site"
    rm -rf "$site"
    "$python" -m pip install -q --no-index --no-deps --no-compile --target "$site" "$kit"/wheels/*.whl \
        || { echo "run: error: pip could not install the kit's wheels into $site" >&2; exit 1; }
    echo "$wanted" > "$stamp"
fi
export PYTHONPATH="$site:$repo${PYTHONPATH:+:$PYTHONPATH}"

# XLA/JAX settings (MuJoCo Playground's for GPUs); a value already set is kept.
#  - full float32 matrix products: the default on Ampere/Hopper is TF32 (10-bit mantissa), too coarse for physics;
#  - Triton GEMM for any matrix product (Playground's setting; faster small-network training).
export JAX_DEFAULT_MATMUL_PRECISION="${JAX_DEFAULT_MATMUL_PRECISION:-highest}"
case " ${XLA_FLAGS:-} " in *xla_gpu_triton_gemm_any*) ;; *) export XLA_FLAGS="${XLA_FLAGS:+$XLA_FLAGS }--xla_gpu_triton_gemm_any=True" ;; esac
export MUJOCO_GL="${MUJOCO_GL:-disable}" PYTHONUNBUFFERED=1
# JAX's persistent compilation cache: a job that compiles what an earlier job compiled (a resumed
# training, the same bench) loads it instead. campaign.sh bundles it as jax_cache.tar.gz; unpack
# that into .kit-cache/ and carry the folder to the next job.
export JAX_COMPILATION_CACHE_DIR="${JAX_COMPILATION_CACHE_DIR:-$repo/.kit-cache/jax}"

cd "$repo"
exec "$python" "$here/kit.py" "$@"
