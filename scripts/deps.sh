#!/usr/bin/env bash
# Installs everything the project needs, idempotently:
#   1. every Debian package listed in deps/apt/*.txt that is not installed yet (sudo only when not root);
#   2. a project-local Python virtualenv in .venv with the pinned requirements/*.txt
#      (re-run only when those files change);
#   3. each deps/post/*.sh hook (component-specific set-up, e.g. the offline PlatformIO platform).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi

mapfile -t wanted < <(sed -e 's/#.*//' -e '/^[[:space:]]*$/d' deps/apt/*.txt | tr -d ' \t' | sort -u)
missing=()
for pkg in "${wanted[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "deps: installing ${#missing[@]} Debian package(s): ${missing[*]}"
  scripts/apt-update.sh
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -q "${missing[@]}"
else
  echo "deps: all ${#wanted[@]} Debian packages present"
fi

if [ ! -x .venv/bin/python ]; then
  echo "deps: creating .venv"
  python3 -m venv .venv
fi
stamp=.venv/.requirements.sha256
want_hash=$(cat requirements/*.txt | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want_hash" ]; then
  echo "deps: installing Python requirements into .venv"
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip
  args=()
  for f in requirements/*.txt; do args+=(-r "$f"); done
  .venv/bin/python -m pip install -q --disable-pip-version-check "${args[@]}"
  echo "$want_hash" > "$stamp"
else
  echo "deps: Python requirements up to date"
fi

for hook in deps/post/*.sh; do
  [ -e "$hook" ] || continue
  bash "$hook"
done
