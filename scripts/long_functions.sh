#!/bin/sh
# Functions longer than N lines (default 150, the limit of the style), longest first:
# "LINES FILE:LINE NAME". Counted by Universal Ctags (function definitions, from the line of the
# name to the closing brace, lambdas inside counted with their function; a TEST body counts as
# one function). Usage: scripts/long_functions.sh [N]
limit=${1:-150}
cd "$(dirname "$0")/.." || exit 1
ctags -x --_xformat='%{line} %{end} %{input} %{name}' --kinds-c++=f --fields=+ne -R \
    --languages=c++ base libmesh io libretina qc app bench tests 2>/dev/null |
    awk -v n="$limit" '{ len = $2 - $1 + 1; if (len > n) print len, $3 ":" $1, $4 }' | sort -rn
