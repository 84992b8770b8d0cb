#!/usr/bin/env bash
# Wall time of the Slurm workflow (submit.sh: reference parts → shards → merge) for
# several array sizes N, one CPU per task, on the cluster SLURM_CONF points at
# (e.g. the local one: eval "$(experiments/slurm/local-cluster.sh env)").
#
#   experiments/slurm/speedup.sh MANIFEST.toml N1 N2 ... > speedup.csv
#
# Every run starts from an empty directory (the reference is rendered too). Prints
# CSV: tasks, reference_s, shards_s, merge_s, total_s, speedup (vs the first N);
# with PHOTONLAB_SPEEDUP_SVG=FILE also draws the speed-up as an SVG bar chart
# (`speedup.sh --svg CSV OUT.svg "LOAD"` redraws one from a CSV).
set -euo pipefail
draw() { # rows on stdin, $1 = load average text
    awk -F, -v cores="$(nproc)" -v load="$1" '
    { n[NR] = $1; s[NR] = $6; t[NR] = $5; if ($6 > max) max = $6; if ($1 > max) max = $1 }
    END {
        W = 120 + 110 * NR; if (W < 620) W = 620; H = 320; top = 40; bot = 260; ymax = max + 0.5
        printf "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" font-family=\"sans-serif\" font-size=\"13\">\n", W, H
        printf "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n"
        printf "<text x=\"%d\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">Slurm workflow speed-up vs array tasks (%d cores, load %s)</text>\n", W / 2, cores, load
        for (v = 0; v <= ymax; v += 1) {
            y = bot - (bot - top) * v / ymax
            printf "<line x1=\"60\" x2=\"%d\" y1=\"%.1f\" y2=\"%.1f\" stroke=\"#ddd\"/><text x=\"52\" y=\"%.1f\" text-anchor=\"end\">%d×</text>\n", W - 20, y, y, y + 4, v
        }
        for (i = 1; i <= NR; i++) {
            x = 90 + 110 * (i - 1); h = (bot - top) * s[i] / ymax
            ideal = (n[i] < cores ? n[i] : cores) / n[1]; yi = bot - (bot - top) * ideal / ymax
            printf "<rect x=\"%d\" y=\"%.1f\" width=\"60\" height=\"%.1f\" fill=\"#4878a8\"/>\n", x, bot - h, h
            printf "<line x1=\"%d\" x2=\"%d\" y1=\"%.1f\" y2=\"%.1f\" stroke=\"#c44\" stroke-width=\"2\" stroke-dasharray=\"5,3\"/>\n", x - 8, x + 68, yi, yi
            printf "<text x=\"%d\" y=\"%.1f\" text-anchor=\"middle\">%.2f× (%.0f s)</text>\n", x + 30, bot - h - 6, s[i], t[i]
            printf "<text x=\"%d\" y=\"%d\" text-anchor=\"middle\">N = %d</text>\n", x + 30, bot + 20, n[i]
        }
        printf "<text x=\"%d\" y=\"%d\" text-anchor=\"middle\" fill=\"#c44\">dashed: ideal min(N, %d cores)</text>\n", W / 2, bot + 45, cores
        printf "</svg>\n"
    }'
}
if [[ ${1:-} == --svg ]]; then # --svg CSV OUT.svg "load average": redraw a measured CSV
    tail -n +2 "$2" | draw "$4" >"$3"
    exit 0
fi
M=${1:?usage: $0 MANIFEST.toml N1 N2 ...}
shift
[[ $# -ge 1 ]] || { echo "usage: $0 MANIFEST.toml N1 N2 ..." >&2; exit 2; }
HERE=$(cd "$(dirname "$0")" && pwd)
TMP=$(mktemp -d /tmp/photonlab-speedup.XXXXXX)
now() { date +%s.%N; }
calc() { awk "BEGIN { printf \"%.4f\", $* }"; }
gone() { [[ -z $(squeue -h -j "$1" -o %i 2>/dev/null) ]]; }
echo "tasks,reference_s,shards_s,merge_s,total_s,speedup"
base=
rows=()
for n in "$@"; do
    out=$TMP/n$n/exp
    t0=$(now)
    ids=$(PHOTONLAB_SBATCH_ARGS="--cpus-per-task=1 ${PHOTONLAB_SBATCH_ARGS:-}" "$HERE/submit.sh" "$M" "$n" --out "$out" 2>/dev/null | tail -n 1)
    read -r _ ref arr mrg <<<"$ids"
    until gone "$ref"; do sleep 0.2; done; t1=$(now)
    until gone "$arr"; do sleep 0.2; done; t2=$(now)
    until gone "$mrg"; do sleep 0.2; done; t3=$(now)
    [[ -f $out/summary.md ]] || { echo "N=$n: no summary.md; logs in $out/logs" >&2; exit 1; }
    total=$(calc "$t3 - $t0")
    base=${base:-$total}
    row=$(printf "%d,%.1f,%.1f,%.1f,%.1f,%.2f" "$n" "$(calc "$t1 - $t0")" "$(calc "$t2 - $t1")" "$(calc "$t3 - $t2")" "$total" "$(calc "$base / $total")")
    echo "$row"
    rows+=("$row")
done
rm -rf "$TMP"
if [[ -n ${PHOTONLAB_SPEEDUP_SVG:-} ]]; then
    printf '%s\n' "${rows[@]}" | draw "$(cut -d' ' -f1-3 /proc/loadavg)" >"$PHOTONLAB_SPEEDUP_SVG"
fi
