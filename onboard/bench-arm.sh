#!/usr/bin/env bash
# `make bench-arm`: per-frame encode cost of every streamer encoding on arm64 and armhf (and x86-64
# for comparison), counted under qemu-user: instructions per frame from an instruction-counting TCG
# plugin (onboard/bench/qemu/insn_count.c), = (count encoding K frames - count loading only) / K,
# plus wall ms per frame under qemu (qemu is not a board: informational) and native x86 ms.
# Needs build/ (make build) and build-arm64/ build-armhf/ (make onboard-arm). Prints a markdown
# table; asserts nothing. Interpretation for Cortex-A9 / A72: docs/onboard.md.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
data=${CODEC_DATA:-tests/data/fr1_xyz_first30}
frames=${CODEC_FRAMES:-20}
plugin_dir=$(mktemp -d)
trap 'rm -rf "$plugin_dir"' EXIT
cc -shared -fPIC -O2 -o "$plugin_dir/insn_count.so" onboard/bench/qemu/insn_count.c

# libjpeg-turbo on armhf enables its NEON code only if /proc/cpuinfo lists "neon"; under qemu-user
# 7.2 that file is the x86 host's, so the plain armhf run measures its scalar C path (a board without
# NEON). The "neon" row forces the NEON path (libjpeg-turbo's JSIMD_FORCENEON), as on a Cortex-A9
# with NEON (the Pandaboard's OMAP4430). arm64 always has NEON (Advanced SIMD is mandatory).
declare -A run=(
  [x86-64]="qemu-x86_64 -plugin $plugin_dir/insn_count.so build/bin/rgbd-codec-cost"
  [arm64]="qemu-aarch64 -cpu cortex-a72 -L / -plugin $plugin_dir/insn_count.so build-arm64/bin/rgbd-codec-cost"
  [armhf]="qemu-arm -cpu cortex-a9 -L / -plugin $plugin_dir/insn_count.so build-armhf/bin/rgbd-codec-cost"
  [armhf-neon]="qemu-arm -cpu cortex-a9 -L / -E JSIMD_FORCENEON=1 -plugin $plugin_dir/insn_count.so build-armhf/bin/rgbd-codec-cost")
count() {  # <arch> <stream> <encoding> <frames> -> "insns wall_ms bytes"
  local out
  out=$(${run[$1]} --data "$data" --stream "$2" --encoding "$3" --frames "$4" 2>&1)
  local insns wall bytes
  insns=$(sed -n 's/^insns: //p' <<<"$out")
  wall=$(sed -n 's/.* \([0-9.]*\) ms\/frame wall.*/\1/p' <<<"$out")
  bytes=$(sed -n 's/.*wall, \([0-9]*\) bytes\/frame/\1/p' <<<"$out")
  echo "$insns $wall $bytes"
}
echo "# encode cost per 640x480 frame, Minsn = million guest instructions ($data, $frames frames; load average $(cut -d' ' -f1-3 /proc/loadavg))"
echo "| encoding | bytes/frame | x86-64 native ms | x86-64 Minsn | arm64 Minsn | armhf Minsn | arm64 qemu ms | armhf qemu ms |"
echo "|---|---|---|---|---|---|---|---|"
for spec in depth:raw depth:rvl depth:zstd-delta rgb:raw rgb:jpeg rgb:jpeg:neon; do
  IFS=: read -r stream encoding variant <<<"$spec"
  armhf=armhf${variant:+-$variant}
  native=$(build/bin/rgbd-codec-cost --data "$data" --stream "$stream" --encoding "$encoding" --frames "$frames")
  native_ms=$(sed -n 's/.* \([0-9.]*\) ms\/frame wall.*/\1/p' <<<"$native")
  row="| $stream $encoding${variant:+ (armhf: $variant forced)}"
  cells=() qemu_ms=()
  bytes=""
  for arch in x86-64 arm64 "$armhf"; do
    read -r base _ _ < <(count "$arch" "$stream" "$encoding" 0)
    read -r total wall b < <(count "$arch" "$stream" "$encoding" "$frames")
    cells+=("$(awk -v t="$total" -v b="$base" -v k="$frames" 'BEGIN{printf "%.1f", (t-b)/k/1e6}')")
    [ "$arch" = x86-64 ] || qemu_ms+=("$wall")
    bytes=$b
  done
  echo "$row | $bytes | $native_ms | ${cells[0]} | ${cells[1]} | ${cells[2]} | ${qemu_ms[0]} | ${qemu_ms[1]} |"
done
