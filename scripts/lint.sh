#!/usr/bin/env bash
# Lint: ruff on every Python file (rules in pyproject.toml [tool.ruff]), a clang-format check
# (.clang-format, Google style at 100 columns) on every tracked C/C++ file (generated headers
# included: their generators format them the same way), the history-word check
# (scripts/check_history_words.py: docs and comments describe the system, not the work on it) and
# the function-size check (scripts/check_function_size.py: no production C++ function over 100
# lines, except those listed with a reason in scripts/function_size_allowlist.txt).
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
status=0

echo "lint: ruff"
.venv/bin/ruff check --quiet . || status=1

if ! command -v clang-format >/dev/null; then
  echo "lint: clang-format is not installed (make deps installs it from deps/apt/base.txt)"
  exit 1
fi
checked=0; unformatted=()
while IFS= read -r f; do
  [ -f "$f" ] || continue
  checked=$((checked + 1))
  clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || unformatted+=("$f")
done < <(git ls-files '*.c' '*.cc' '*.cpp' '*.h' '*.hpp')
echo "lint: clang-format: $checked files checked"
if [ "${#unformatted[@]}" -gt 0 ]; then
  echo "lint: not in clang-format style (run clang-format -i on them):"; printf '  %s\n' "${unformatted[@]}"
  status=1
fi
echo "lint: history words"
python3 scripts/check_history_words.py || status=1
echo "lint: function size"
python3 scripts/check_function_size.py || status=1
exit $status
