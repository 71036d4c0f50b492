#!/usr/bin/env bash
# Fails, naming the files, if any C++ file of the tree is not as clang-format (.clang-format)
# writes it. Usage: scripts/check-format.sh [ROOT]   (fix: clang-format -i FILE...)
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"
command -v clang-format > /dev/null || { echo "check-format: clang-format not found (Debian: apt-get install clang-format)" >&2; exit 1; }
if git rev-parse --is-inside-work-tree > /dev/null 2>&1; then
  mapfile -t files < <(git ls-files '*.cpp' '*.h' | grep -v '^third_party/')
else
  mapfile -t files < <(find src server client proto tools tests \( -name '*.cpp' -o -name '*.h' \) | sort)
fi
[ "${#files[@]}" -gt 0 ] || { echo "check-format: no C++ files found under $(pwd)" >&2; exit 1; }
bad=()
for f in "${files[@]}"; do
  clang-format --dry-run --Werror "$f" > /dev/null 2>&1 || bad+=("$f")
done
if [ "${#bad[@]}" -gt 0 ]; then
  printf 'check-format: not formatted (clang-format -i FILE): %s\n' "${bad[@]}" >&2
  exit 1
fi
echo "check-format: OK (${#files[@]} files, $(clang-format --version | grep -o 'version [0-9.]*'))"
