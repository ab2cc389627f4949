#!/usr/bin/env bash
# Learning ablations on one GPU: several benchmarks/learning_cpu.py trainings side by side, one per
# variant, then one bundle of their runs (policy, last checkpoint, curves) to evaluate elsewhere.
#
#   scripts/device/ablations.sh [--minutes M] [--results DIR] [--feet F] [--preset P] [--num-envs N]
#                               [--kit DIR] VARIANT [VARIANT...] [-- learning_cpu.py options]
#
# VARIANT: learning_cpu.py's --variant ('+'-joined tokens, e.g. position+ppo). Each job trains
# --num-envs robots (default 2048, the paper's) with 24-step unrolls and 4 minibatches (legged_gym's
# rollout), without evaluations (pipelines/evaluate.py measures each policy's verdict afterwards),
# and stops at its last checkpoint before --minutes (default 6.5). Jobs share the GPU: its memory
# split evenly, their throughput not a benchmark (each job's steps/s is recorded in its curve).
# Uses the offline kit (scripts/device/prepare.sh) like run.sh: its wheels installed into
# $KIT_SITE, the machine's own JAX.
# Writes into --results (default $OUT, else results/): ablations.tar.gz (every run folder with its
# policy and latest checkpoint, each job's log), summary.jsonl (each job's last JSON line),
# gpu_util.log (nvidia-smi every 15 s) and jax_cache.tar.gz when the compilation cache fits 16 MiB.
# Exit codes: 0 every job done, 1 one failed, 2 usage error.
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
results="${OUT:-results}"
minutes=6.5
feet=ball
preset=full
num_envs=2048
kit="$repo/.kit"
variants=()
extra=()
while [[ $# -gt 0 ]]; do
    case "$1" in
        --minutes) minutes="$2"; shift 2 ;;
        --results) results="$2"; shift 2 ;;
        --feet) feet="$2"; shift 2 ;;
        --preset) preset="$2"; shift 2 ;;
        --num-envs) num_envs="$2"; shift 2 ;;
        --kit) kit="$2"; shift 2 ;;
        --) shift; extra=("$@"); break ;;
        -*) echo "ablations: error: unknown option $1" >&2; exit 2 ;;
        *) variants+=("$1"); shift ;;
    esac
done
if [[ ${#variants[@]} -eq 0 ]]; then
    echo "usage: $0 [--minutes M] [--results DIR] [--feet F] [--preset P] [--num-envs N] [--kit DIR] VARIANT [VARIANT...] [-- options]" >&2
    exit 2
fi
mkdir -p "$results" || exit 2
results="$(cd "$results" && pwd)"

# The kit's wheels, installed as run.sh installs them (run.sh --help installs, then exits 0).
"$here/run.sh" --kit "$kit" --help >/dev/null || { echo "ablations: error: the kit did not install" >&2; exit 1; }
export PYTHONPATH="${KIT_SITE:-/tmp/site}:$repo${PYTHONPATH:+:$PYTHONPATH}"
export JAX_DEFAULT_MATMUL_PRECISION="${JAX_DEFAULT_MATMUL_PRECISION:-highest}"
case " ${XLA_FLAGS:-} " in *xla_gpu_triton_gemm_any*) ;; *) export XLA_FLAGS="${XLA_FLAGS:+$XLA_FLAGS }--xla_gpu_triton_gemm_any=True" ;; esac
export MUJOCO_GL="${MUJOCO_GL:-disable}" PYTHONUNBUFFERED=1
export JAX_COMPILATION_CACHE_DIR="${JAX_COMPILATION_CACHE_DIR:-$repo/.kit-cache/jax}"
export XLA_PYTHON_CLIENT_MEM_FRACTION="${XLA_PYTHON_CLIENT_MEM_FRACTION:-$(python3 -c "print(round(0.9 / ${#variants[@]}, 3))")}"

work="$(mktemp -d "${TMPDIR:-/tmp}/footforge-ablations-XXXXXX")"
( while true; do date +%T; nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>&1; sleep 15; done ) \
    >"$results/gpu_util.log" 2>&1 &
sampler=$!
pids=()
names=()
trap 'kill $sampler ${pids[*]} 2>/dev/null' INT TERM EXIT
for variant in "${variants[@]}"; do
    name="${feet}_${preset}_${variant//+/-}"
    echo "ablations: $name"
    # A hard limit beside the budget: the stop acts only at an epoch's end, a hang must not outlive the call.
    timeout "$(python3 -c "print(int($minutes * 60 + 240))")" python3 "$repo/benchmarks/learning_cpu.py" --out "$work/$name" --feet "$feet" --preset "$preset" \
        --variant "$variant" --num-envs "$num_envs" --unroll-length 24 --batch-size $((num_envs / 4)) --minibatches 4 \
        --timesteps 200000000 --eval-every 1000000 --no-evaluations --max-minutes "$minutes" \
        --build-dir "$kit/build/$feet" --no-verdict "${extra[@]}" >"$work/$name.log" 2>&1 &
    pids+=($!)
    names+=("$name")
    sleep 2
done
failed=0
: >"$results/summary.jsonl"
for i in "${!pids[@]}"; do
    wait "${pids[$i]}"
    code=$?
    echo "ablations: ${names[$i]} exited $code: $(grep -v '^{' "$work/${names[$i]}.log" | tail -1)"
    grep '^{' "$work/${names[$i]}.log" | tail -1 >>"$results/summary.jsonl"
    (( code == 0 )) || failed=1
    # Only the latest checkpoint of each run travels back.
    ckpts=("$work/${names[$i]}"/checkpoints/*/)
    (( ${#ckpts[@]} > 1 )) && rm -rf "${ckpts[@]:0:${#ckpts[@]}-1}"
done
tar -czf "$results/ablations.tar.gz" -C "$work" . && echo "ablations: $(du -h "$results/ablations.tar.gz" | cut -f1) in ablations.tar.gz"
cache="$JAX_COMPILATION_CACHE_DIR"
if [[ -d "$cache" ]]; then
    tar -czf "$results/jax_cache.tar.gz" -C "$(dirname "$cache")" "$(basename "$cache")"
    if (( $(stat -c %s "$results/jax_cache.tar.gz") > 16 * 1024 * 1024 )); then
        echo "ablations: the compilation cache is $(du -sh "$cache" | cut -f1): not bundled"
        rm -f "$results/jax_cache.tar.gz"
    fi
fi
exit $failed
