#!/usr/bin/env bash
# `apt-get update` that survives a Debian mirror caught mid-sync ("File has unexpected size ...
# Mirror sync in progress?"), which fails the whole update for one index file: retried
# APT_UPDATE_TRIES times (default 3) APT_UPDATE_WAIT_S apart (default 20 s; a mirror sync
# finishes in minutes). If every try fails, it warns and returns 0: apt keeps the indexes that did
# download, and the `apt-get install` after it fails by itself, naming the package, if one is
# really unavailable. Used by scripts/deps.sh and deps/post/*.sh.
set -uo pipefail
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
tries=${APT_UPDATE_TRIES:-3}
wait_s=${APT_UPDATE_WAIT_S:-20}
for ((i = 1; i <= tries; i++)); do
  if "${sudo_cmd[@]}" apt-get update -q; then exit 0; fi
  if [ "$i" -lt "$tries" ]; then
    echo "apt-update: apt-get update failed (try $i of $tries); retrying in ${wait_s} s" >&2
    sleep "$wait_s"
  fi
done
echo "apt-update: WARNING: apt-get update failed $tries times; installing from the indexes that did download" >&2
exit 0
