#!/usr/bin/env bash
# Several kit jobs at once on one GPU (each a run.sh job in its own process), then one bundle.
#
#   scripts/device/campaign.sh [--results DIR] [--minutes M] [--kit DIR] [--cpu] SPEC [SPEC...]
#
# SPEC: one run.sh job with its arguments, quoted, e.g. "train-flat ball B" or
# "--resume in/flat_aof_B.tar.gz train-flat aof B -- --checkpoint-every 2000000".
# One MJX training of the paper's 2048 robots leaves most of an H100 idle (MJX steps are many
# small kernels) and compiling takes one core for minutes: jobs side by side use the GPU and the
# machine's cores together. Each job gets 1/N of the GPU memory (XLA_PYTHON_CLIENT_MEM_FRACTION,
# unless set) and --minutes of wall time. Throughput of jobs that shared the GPU is not a
# benchmark: run `bench` alone for that.
#
# --cpu: the jobs run on the machine's CPU cores instead (JAX_PLATFORMS=cpu, so training's physics is
# MuJoCo's C engine, footforge.envs.engine), each pinned with taskset to its own equal share of the cores
# this script may use (kit.py --core-share). A run trained on a 2-core CPU under the `cpu` presets (128
# robots) resumes so with its whole configuration and engine; MJX on a GPU steps such small batches
# slower than the C engine on a few cores. Limit the cores with taskset to leave some for a GPU campaign
# run beside it (docs/training.md).
#
# Writes into --results (default $OUT, else results/): NAME.summary.json for each job (NAME from
# its job and arguments, e.g. train-flat_ball_B) and campaign.tar.gz (every job's results folder:
# summary, log, RUN.tar.gz), so that few files come back. Exit codes: 0 every job done, 1 one
# failed, 2 usage error.
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
results="${OUT:-results}"
minutes=9
kit_args=()
cpu=0
while [[ $# -gt 0 && "$1" == --* ]]; do
    case "$1" in
        --results) results="$2"; shift 2 ;;
        --minutes) minutes="$2"; shift 2 ;;
        --kit) kit_args=(--kit "$2"); shift 2 ;;
        --cpu) cpu=1; shift ;;
        *" "*) break ;;  # a SPEC that begins with one of run.sh's options ("--resume X train-flat ...")
        *) echo "campaign: error: unknown option $1" >&2; exit 2 ;;
    esac
done
if [[ $# -eq 0 ]]; then
    echo "usage: $0 [--results DIR] [--minutes M] [--kit DIR] [--cpu] SPEC [SPEC...]  (SPEC: a quoted run.sh job)" >&2
    exit 2
fi
mkdir -p "$results" || exit 2

# Install the wheels once (run.sh installs before the job starts; kit.py --help then exits 0).
"$here/run.sh" "${kit_args[@]}" --help >/dev/null || { echo "campaign: error: the kit did not install" >&2; exit 1; }
# The jobs' results folders, bundled into campaign.tar.gz at the end and then removed.
work="$(mktemp -d "${TMPDIR:-/tmp}/footforge-campaign-XXXXXX")" || { echo "campaign: error: no temporary folder" >&2; exit 1; }
trap 'rm -rf "$work"' EXIT
trap 'kill $(jobs -p) 2>/dev/null' INT TERM
export XLA_PYTHON_CLIENT_MEM_FRACTION="${XLA_PYTHON_CLIENT_MEM_FRACTION:-$(python3 -c "print(round(0.9 / $#, 3))")}"
if (( cpu )); then
    export JAX_PLATFORMS=cpu
    command -v taskset >/dev/null || echo "campaign: no taskset here: the --cpu jobs share every core"
fi

names=()
pids=()
for spec in "$@"; do
    read -r -a words <<<"$spec"
    name=""
    skip=0
    for w in "${words[@]}"; do  # the job and its arguments, without options and extra arguments
        if [[ "$w" == "--" ]]; then break; fi
        if (( skip )); then skip=0; continue; fi
        if [[ "$w" == --* ]]; then skip=1; continue; fi
        name="${name:+${name}_}$w"
    done
    mkdir -p "$work/$name"
    pin=()
    if (( cpu )) && command -v taskset >/dev/null; then
        pin=(taskset -c "$(python3 "$here/kit.py" --core-share $# ${#pids[@]})")
    fi
    echo "campaign: $name: ${pin[*]}${pin:+ }run.sh --results $work/$name --minutes $minutes $spec"
    "${pin[@]}" "$here/run.sh" "${kit_args[@]}" --results "$work/$name" --minutes "$minutes" "${words[@]}" \
        >"$work/$name/stdout.log" 2>&1 &
    pids+=($!)
    names+=("$name")
    sleep 2  # staggered: the jobs' first steps (linking builds, unpacking) do not collide
done

failed=0
for i in "${!pids[@]}"; do
    wait "${pids[$i]}"
    code=$?
    name="${names[$i]}"
    echo "campaign: $name exited $code: $(tail -1 "$work/$name/stdout.log")"
    if [[ -f "$work/$name/summary.json" ]]; then cp "$work/$name/summary.json" "$results/$name.summary.json"; fi
    (( code == 0 )) || failed=1
done
tar -czf "$results/campaign.tar.gz" -C "$work" . && echo "campaign: $(du -h "$results/campaign.tar.gz" | cut -f1) in $results/campaign.tar.gz"
# The compilation cache (run.sh's JAX_COMPILATION_CACHE_DIR) for the next job, when it fits one result file.
cache="${JAX_COMPILATION_CACHE_DIR:-$(cd "$here/../.." && pwd)/.kit-cache/jax}"
if [[ -d "$cache" ]]; then
    tar -czf "$results/jax_cache.tar.gz" -C "$(dirname "$cache")" "$(basename "$cache")"
    if (( $(stat -c %s "$results/jax_cache.tar.gz") > 16 * 1024 * 1024 )); then
        echo "campaign: the compilation cache is over 16 MiB ($(du -sh "$cache" | cut -f1)); not bundled"
        rm -f "$results/jax_cache.tar.gz"
    else
        echo "campaign: $(du -h "$results/jax_cache.tar.gz" | cut -f1) in $results/jax_cache.tar.gz (unpack into .kit-cache/ and carry it)"
    fi
fi
exit $failed
