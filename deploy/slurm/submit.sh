#!/usr/bin/env bash
# Submit a sharded relight bake to Slurm: an array job of N parts, then a merge job that
# runs only if every part succeeded (--dependency=afterok).
#
#   deploy/slurm/submit.sh [--wait] [--cpus C] SCENE.json OUT.relight N [relight bake options...]
#
# Parts go to OUT.parts/ (with each task's log). --wait blocks until the merge job ends and
# exits with its status. Extra sbatch options (partition, account, time limit) can be given
# in $RELIGHT_SBATCH_OPTS; the relight binary is $RELIGHT, else `relight` on PATH (it must
# be reachable at that path on the compute nodes, and SCENE/OUT on a shared file system).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
wait=()
cpus=()
while [ $# -gt 0 ]; do
    case $1 in
        --wait) wait=(--wait); shift ;;
        --cpus) cpus=(--cpus-per-task "$2"); shift 2 ;;
        *) break ;;
    esac
done
if [ $# -lt 3 ]; then
    echo "usage: $0 [--wait] [--cpus C] SCENE.json OUT.relight N [relight bake options...]" >&2
    exit 2
fi
scene=$(realpath "$1")
out=$(realpath -m "$2")
n=$3
shift 3
if ! [[ $n =~ ^[0-9]+$ ]] || [ "$n" -lt 1 ]; then
    echo "$0: N must be a positive number, not '$n'" >&2
    exit 2
fi
parts="${out%.relight}.parts"
mkdir -p "$parts"
# shellcheck disable=SC2086
bake=$(sbatch --parsable ${RELIGHT_SBATCH_OPTS:-} "${cpus[@]}" --array="0-$((n - 1))" \
    --output="$parts/slurm-%A_%a.out" "$here/bake-part.sbatch" "$scene" "$parts" "$@")
bake=${bake%%;*}
echo "submitted bake array job $bake ($n parts into $parts)"
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${RELIGHT_SBATCH_OPTS:-} --dependency="afterok:$bake" \
    --kill-on-invalid-dep=yes --output="$parts/slurm-merge-%j.out" "${wait[@]}" \
    "$here/merge.sbatch" "$parts" "$n" "$out")
merge=${merge%%;*}
echo "merge job $merge -> $out"
if [ ${#wait[@]} -gt 0 ]; then
    # sbatch --wait returns 0 for a job cancelled because a part failed: ask Slurm.
    state=$(scontrol show job -o "$merge" | grep -o 'JobState=[A-Z_]*' || true)
    if [ "$state" != "JobState=COMPLETED" ]; then
        echo "$0: the merge job $merge ended with ${state:-an unknown state}: a part failed? logs in $parts/" >&2
        exit 1
    fi
fi
