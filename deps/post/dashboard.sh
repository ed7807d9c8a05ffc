#!/usr/bin/env bash
# Dashboard browser libraries (offboard/dashboard/package.json, versions locked in package-lock.json):
# uPlot (history plots) and fzstd (zstd chunks of a recording loaded in the page). npm ci installs
# them into offboard/dashboard/node_modules; the files the page loads are copied into
# offboard/dashboard/static/ (git-ignored) so quad-control serves them from the project and the
# browser fetches nothing from elsewhere. Idempotent: skipped when the copies match the lock file.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
dash=$root/offboard/dashboard
stamp=$dash/node_modules/.rgbdquad-lock.sha256
want=$(sha256sum "$dash/package-lock.json" | cut -d' ' -f1)
if ! command -v npm >/dev/null 2>&1; then
  echo "deps: installing npm (dashboard libraries)"
  sudo_cmd=()
  if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q npm
fi
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "deps: installing dashboard libraries (npm ci)"
  (cd "$dash" && npm ci --no-audit --no-fund --loglevel=error)
  echo "$want" > "$stamp"
fi
cp "$dash/node_modules/uplot/dist/uPlot.iife.min.js" "$dash/static/uPlot.iife.min.js"
cp "$dash/node_modules/uplot/dist/uPlot.min.css" "$dash/static/uPlot.min.css"
cp "$dash/node_modules/fzstd/umd/index.js" "$dash/static/fzstd.umd.js"
