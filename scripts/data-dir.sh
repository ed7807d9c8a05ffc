#!/usr/bin/env bash
# Prints the DATA folder that make bench / make study read when DATA is not set, relative to the
# repository root: ../shared/data while it exists, else data/tum, the folder `make data`
# fills (scripts/get_tum.py; docs/data.md). The Makefile and the bench/study scripts all ask here.
root=$(cd "$(dirname "$0")/.." && pwd)
if [ -d "$root/../shared/data" ]; then echo ../shared/data; else echo data/tum; fi
