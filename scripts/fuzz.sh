#!/usr/bin/env bash
# Runs every libFuzzer target in build-fuzz/ (named fuzz_*) for FUZZ_SECONDS each, starting from its
# seed corpus (the golden vectors). `make test` runs this with a short budget (~60 s in total);
# `make fuzz` with a long one. Any crash, leak, timeout or OOM fails the run; reproducers are
# written to test-artifacts/fuzz/.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
mapfile -t targets < <(find build-fuzz -maxdepth 4 -type f -name 'fuzz_*' -perm -u+x | sort)
if [ "${#targets[@]}" -eq 0 ]; then
  echo "fuzz: no fuzz targets built"; exit 1
fi
total=${FUZZ_TOTAL_SECONDS:-}
per=${FUZZ_SECONDS:-300}
if [ -n "$total" ]; then per=$(( total / ${#targets[@]} )); [ "$per" -ge 1 ] || per=1; fi
mkdir -p test-artifacts/fuzz
status=0
for t in "${targets[@]}"; do
  name=$(basename "$t")
  seeds="protocol/vectors/corpus/${name#fuzz_}"
  case "$name" in  # targets of tests/fuzz: stream sessions start from the stream vectors
    fuzz_receiver_session|fuzz_sender_session) seeds=protocol/vectors/corpus/stream ;;
    fuzz_dashboard_request|fuzz_dashboard_api|fuzz_slam_connection) seeds=tests/fuzz/corpus/${name#fuzz_} ;;
  esac
  work=$(mktemp -d)
  [ -d "$seeds" ] && cp -r "$seeds"/. "$work"/ 2>/dev/null || true
  echo "fuzz: $name for ${per}s (seeds: $seeds)"
  if ! "$t" "$work" -max_total_time="$per" -rss_limit_mb=1024 -timeout=5 -max_len=65536 \
       -artifact_prefix="test-artifacts/fuzz/${name}-" -print_final_stats=1 2> "test-artifacts/fuzz/$name.log"; then
    echo "fuzz: $name FAILED (see test-artifacts/fuzz/$name.log)"; status=1
  fi
  grep -E 'stat::number_of_executed_units|stat::peak_rss_mb' "test-artifacts/fuzz/$name.log" | sed "s/^/fuzz: $name /" || true
  rm -rf "$work"
done
exit $status
