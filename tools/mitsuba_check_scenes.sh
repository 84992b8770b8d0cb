#!/bin/sh
# Renders every experiments/scenes/mi-*.xml with photonlab `path` and with Mitsuba 3
# and prints the comparison (tools/mitsuba_compare_xml.py). Usage:
#   tools/mitsuba_check_scenes.sh [OUT_DIR] [RES] [PL_SPP] [MI_SPP]
set -e
out=${1:-results/mitsuba-check}; res=${2:-128}; pl_spp=${3:-1024}; mi_spp=${4:-4096}
export DRJIT_LIBLLVM_PATH=${DRJIT_LIBLLVM_PATH:-/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1}
mkdir -p "$out"
for f in experiments/scenes/mi-*.xml; do
    s=$(basename "$f" .xml)
    grep -q "<sensor" "$f" || continue   # included fragments
    echo "== $s ($res px, photonlab $pl_spp spp, mitsuba $mi_spp spp)"
    target/release/photonlab render --scene "$f" --integrator path --spp "$pl_spp" --resolution "${res}x${res}" \
        -o "$out/$s-photonlab.exr" --quiet 2>&1 | grep -E "^time" || true
    python3 tools/mitsuba_compare_xml.py "$f" --spp "$mi_spp" -D res="$res" --out "$out/$s-mitsuba.exr" \
        --photonlab "$out/$s-photonlab.exr" | tail -2
done
