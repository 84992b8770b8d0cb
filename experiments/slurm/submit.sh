#!/usr/bin/env bash
# Submits a photonlab experiment to Slurm as three dependent jobs:
#
#   experiments/slurm/submit.sh MANIFEST.toml N [photonlab run flags, e.g. --out DIR]
#
#   1. reference: an array of N tasks, each rendering 1/N of every reference's samples
#      (`run --reference-only --shard I/N`); the last part assembles the reference
#   2. shards: an array of N tasks, `run --shard I/N`, after the reference (afterok)
#   3. merge: `photonlab merge DIR`, after every shard (afterok)
#
# Run from the repository root after `cargo build --release`. Logs go to
# DIR/logs/{reference,shard}-JOB_TASK.out and DIR/logs/merge-JOB.out (DIR =
# results/NAME or --out). Extra sbatch options for all three jobs:
# PHOTONLAB_SBATCH_ARGS (e.g. "--partition=short --cpus-per-task=4"). The results
# directory must be on a file system every node shares; PHOTONLAB_UNSHARED=1 skips
# that check and the merge job (merge by hand: photonlab merge DIR OTHER_DIR ...).
# Prints "jobs REF SHARDS MERGE" on stdout.
set -euo pipefail
fail() { echo "submit.sh: $*" >&2; exit 2; }
[[ $# -ge 2 ]] || fail "usage: $0 MANIFEST.toml N [photonlab run flags]"
M=$1 N=$2
shift 2
[[ $N =~ ^[1-9][0-9]*$ ]] || fail "N must be a positive number of array tasks, got '$N'"
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=$(realpath "${PHOTONLAB:-target/release/photonlab}" 2>/dev/null) || fail "no photonlab binary (cargo build --release, or set PHOTONLAB)"
[[ -x $BIN ]] || fail "$BIN is not executable"
command -v sbatch >/dev/null || fail "sbatch not found: is this a Slurm submit host?"
# The manifest is checked (and its output directory found) before anything is queued.
listing=$("$BIN" run "$M" --list "$@") || fail "$M: not a valid manifest (see above)"
OUT=$(tail -n 1 <<<"$listing" | sed -n 's/.*, output //p')
[[ -n $OUT ]] || fail "cannot find the output directory of $M"
mkdir -p "$OUT/logs"
TOKEN="$(date +%s%N)-$$-$RANDOM"
echo "$TOKEN" >"$OUT/.slurm-submit-token"
export PHOTONLAB=$BIN PHOTONLAB_OUT=$OUT PHOTONLAB_SUBMIT_TOKEN=$TOKEN
read -r -a EXTRA <<<"${PHOTONLAB_SBATCH_ARGS:-}"
ref=$(sbatch --parsable "${EXTRA[@]}" --array=1-"$N" --job-name=photonlab-ref --output="$OUT/logs/reference-%A_%a.out" \
    "$HERE/shard.sbatch" "$M" --reference-only "$@")
arr=$(sbatch --parsable "${EXTRA[@]}" --array=1-"$N" --dependency=afterok:"$ref" --job-name=photonlab-shard \
    --output="$OUT/logs/shard-%A_%a.out" "$HERE/shard.sbatch" "$M" "$@")
if [[ -n ${PHOTONLAB_UNSHARED:-} ]]; then
    echo "reference $ref, shards $arr; no merge job (PHOTONLAB_UNSHARED): copy each node's $OUT, then $BIN merge $OUT OTHER_DIR ..." >&2
    echo "jobs $ref $arr -"
    exit 0
fi
mrg=$(sbatch --parsable "${EXTRA[@]}" --dependency=afterok:"$arr" --output="$OUT/logs/merge-%j.out" "$HERE/merge.sbatch" "$OUT")
echo "reference $ref (array 1-$N), shards $arr (array 1-$N), merge $mrg; logs in $OUT/logs/, results in $OUT/summary.md" >&2
echo "jobs $ref $arr $mrg"
