#!/usr/bin/env bash
# Builds revolve's libFuzzer targets with clang-16 (ASan + UBSan) and runs them:
#   tests/fuzz/fuzz.sh [--seconds N] [--build-dir DIR] [TARGET...]
# For each target: replays the committed seed corpus (corpus/TARGET) and every kept crash
# (regressions/TARGET), then fuzzes for N seconds (default 3) from a scratch copy of the corpus.
# A crash fails the run; its input is left in DIR/crashes/TARGET: add it to regressions/TARGET
# once the bug is fixed. Exits 77 (ctest: skipped) when clang-16 or libFuzzer is missing.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
seconds=3
build_dir="${here}/../../build/fuzz"
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds="$2"; shift 2 ;;
    --build-dir) build_dir="$2"; shift 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
[ ${#targets[@]} -gt 0 ] || targets=(config cameras manifest protocol image_header image_decode calibration)

if ! command -v clang++-16 >/dev/null; then
  echo "fuzz: clang++-16 not found (apt-get install clang-16 libfuzzer-16-dev libclang-rt-16-dev): skipped" >&2
  exit 77
fi
if ! echo 'extern "C" int LLVMFuzzerTestOneInput(const char*, unsigned long) { return 0; }' |
    clang++-16 -x c++ -fsanitize=fuzzer - -o /dev/null 2>/dev/null; then
  echo "fuzz: clang-16 cannot link -fsanitize=fuzzer (apt-get install libfuzzer-16-dev libclang-rt-16-dev, its runtime): skipped" >&2
  exit 77
fi

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
if [ ! -f "${build_dir}/build.ninja" ]; then
  cmake -S "$here" -B "$build_dir" -G Ninja -DCMAKE_CXX_COMPILER=clang++-16 "${launcher[@]}" \
    >/dev/null
fi
cmake --build "$build_dir" -j 2 >/dev/null || cmake --build "$build_dir" -j 1

status=0
for t in "${targets[@]}"; do
  bin="${build_dir}/fuzz_${t}"
  crashes="${build_dir}/crashes/${t}"
  scratch="${build_dir}/scratch/${t}"
  rm -rf "$scratch"
  mkdir -p "$crashes" "$scratch"
  cp -r "${here}/corpus/${t}/." "$scratch/" 2>/dev/null || true
  # Replay: every committed input, seeds and kept crashes, once.
  inputs=()
  for f in "${here}/corpus/${t}"/* "${here}/regressions/${t}"/*; do
    [ -f "$f" ] && inputs+=("$f")
  done
  if [ ${#inputs[@]} -gt 0 ] &&
      ! "$bin" -runs=0 "${inputs[@]}" >"${build_dir}/${t}.replay.log" 2>&1; then
    echo "fuzz: ${t}: a committed input fails (see ${build_dir}/${t}.replay.log)" >&2
    tail -n 30 "${build_dir}/${t}.replay.log" >&2
    status=1
    continue
  fi
  if ! "$bin" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=1024 -max_len=65536 \
      -artifact_prefix="${crashes}/" -print_final_stats=1 "$scratch" \
      >"${build_dir}/${t}.log" 2>&1; then
    echo "fuzz: ${t}: found a failing input in ${crashes} (log ${build_dir}/${t}.log)" >&2
    tail -n 40 "${build_dir}/${t}.log" >&2
    status=1
    continue
  fi
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "${build_dir}/${t}.log" | grep -o '[0-9]*$' || echo '?')
  echo "fuzz: ${t}: ${#inputs[@]} committed inputs replayed, ${runs} runs in ${seconds} s, no failure"
done
exit $status
