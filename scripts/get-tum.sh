#!/usr/bin/env bash
# `make data`: download the TUM RGB-D sequences the benchmarks read, verify each archive against its
# pinned size and sha256, unpack it and cut the benchmark excerpts (scripts/get_tum.py; docs/data.md).
#   scripts/get-tum.sh [SEQ...] [--root DIR] [--trust-on-first-use] [--list] [--help]
# Standard-library Python only: runs before `make deps`.
set -euo pipefail
exec python3 "$(dirname "$0")/get_tum.py" "$@"
