#!/usr/bin/env bash
# clang-tidy over the project's sources (the checks in .clang-tidy; every warning is an error).
#   tests/lint/clang_tidy.sh BUILD_DIR            the files this change touched (see below)
#   tests/lint/clang_tidy.sh BUILD_DIR --all      every source file outside tests/
# The whole tree takes ~10 s of CPU per file (~8 minutes on 2 cores), too long for every CI run, so
# the test suite checks what changed: the .cc files changed since the merge base with origin/main
# when there is such a branch, else since the newest commit older than REVOLVE_TIDY_SINCE
# (default "24 hours ago"), plus the .cc file beside each changed header. `./run tidy` runs it
# all. Exit 77 (skipped) when clang-tidy-16 is not installed.
set -euo pipefail
build_dir=$(realpath "$1")
shift
cd "$(dirname "$0")/../.."

tidy=$(command -v clang-tidy-16 || true)
if [ -z "$tidy" ]; then
  echo "clang-tidy-16 is not installed: skipped (./run installs it)"
  exit 77
fi

# clang-tidy 16 does not know -std=c++23 and needs the C++20 concepts level that libstdc++ 12
# requires for <expected>; it gets a copy of the compile commands with that spelled out, without
# the GCC-only options (the vectoriser's cost model).
mkdir -p "$build_dir/tidy"
sed -e 's/-std=c++23/-std=c++2b -U__cpp_concepts -D__cpp_concepts=202002L -Wno-builtin-macro-redefined/g; s/-Wshadow=local/-Wshadow/g; s/-fvect-cost-model=[a-z]*//g' \
  "$build_dir/compile_commands.json" >"$build_dir/tidy/compile_commands.json"

all_sources() { git ls-files '*.cc' | grep -v '^tests/'; }

if [ "${1:-}" = "--all" ] || ! git rev-parse --git-dir >/dev/null 2>&1; then
  files=$(all_sources)
else
  if git rev-parse --verify -q origin/main >/dev/null; then
    base=$(git merge-base HEAD origin/main)
  else
    base=$(git rev-list -1 --before="${REVOLVE_TIDY_SINCE:-24 hours ago}" HEAD || true)
  fi
  if [ -z "$base" ]; then
    files=$(all_sources)  # a history younger than that: all of it
  else
    changed=$(git diff --name-only --diff-filter=AMR "$base" -- '*.cc' '*.h' | grep -v '^tests/' || true)
    files=$(for f in $changed; do
      case "$f" in
        *.cc) echo "$f" ;;
        *.h) if [ -f "${f%.h}.cc" ]; then echo "${f%.h}.cc"; fi ;;
      esac
    done | sort -u)
    echo "clang-tidy on the $(echo "$files" | grep -c . || true) source file(s) changed since ${base:0:12}"
  fi
fi
[ -n "$files" ] || { echo "no source file to check"; exit 0; }
echo "$files" | xargs -P "$(nproc)" -n 2 "$tidy" -p "$build_dir/tidy" --quiet
echo "clang-tidy: clean"
