#!/usr/bin/env bash
# Functions longer than a limit (default 150 lines, CONTRIBUTING.md,
# "Style") in the core, the SDK, the plugins and the tools: one line each,
# longest first, "LINES FILE:LINE NAME"; exit 1 if there is any. Counts a
# definition from its first line to its closing brace, lambdas inside
# included, with Universal Ctags (Debian: universal-ctags).
#   tools/style/long_functions.sh [LIMIT]
set -euo pipefail
cd "$(dirname "$0")/../.."
limit=${1:-150}
ctags --version 2> /dev/null | grep -q "Universal Ctags" ||
  { echo "long_functions: needs Universal Ctags (Debian: universal-ctags)" >&2; exit 2; }
list=$(mktemp)
trap 'rm -f "$list"' EXIT
ctags -R --languages=C,C++ --kinds-C++=f --kinds-C=f --fields=+ne -o - core sdk plugins tools |
  awk -F'\t' -v limit="$limit" '{
    line = ""; end = ""
    for (i = 4; i <= NF; i++) {
      if ($i ~ /^line:/) line = substr($i, 6)
      if ($i ~ /^end:/) end = substr($i, 5)
    }
    if (end != "" && end - line + 1 > limit) print end - line + 1, $2 ":" line, $1
  }' | sort -rn > "$list"
if [ -s "$list" ]; then
  cat "$list"
  exit 1
fi
