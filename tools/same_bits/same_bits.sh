#!/usr/bin/env bash
# Same bits: runs the identity scenarios with two builds of Talus and
# compares every output file byte for byte (the provenance record, which
# names the build and the time, aside). A change that must not change a
# result (a refactor, a build change) leaves them identical at 1 and 2
# threads.
#   tools/same_bits/same_bits.sh BUILD_A BUILD_B [WORK]
# (SAME_BITS_ONLY=REGEX runs the scenarios whose names match it.)
# BUILD_A and BUILD_B are build folders (bin/talus, bin/talus_bench). The
# scenarios: every configs/**/*.yaml, and the benchmark blocks of
# talus_bench (2D and 3D, linear_elastic and mohr_coulomb) cut to a short
# time, so that the whole set runs in minutes. Each build runs with the
# plugins beside it (no TALUS_PLUGIN_PATH, a HOME of its own), and each
# run's provenance record must name them. The kernels are the widest the
# CPU has; TALUS_KERNEL_ISA=generic or avx2 compares another version.
set -euo pipefail
a=$(cd "$1" && pwd) b=$(cd "$2" && pwd)
work=${3:-$(mktemp -d)}
src=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$work/scenarios" "$work/home"
unset TALUS_PLUGIN_PATH XDG_DATA_HOME
export HOME=$work/home
for f in "$src"/configs/*/*.yaml; do
  cp "$f" "$work/scenarios/$(basename "$(dirname "$f")")_$(basename "$f")"
done
# The blocks to 0.002 s: 200-300 steps of a million particles each.
for c in 2d_block_bspline2_linear_elastic 3d_block_bspline2_linear_elastic \
         2d_block_bspline2_mohr_coulomb 3d_block_bspline2_mohr_coulomb; do
  bench=$b/bin/talus_bench
  "$bench" --scenario "$c" > /dev/null 2>&1 || bench=$a/bin/talus_bench
  "$bench" --scenario "$c" | sed 's/^time: {end: 1.0}$/time: {end: 0.002}/' \
    > "$work/scenarios/bench_$c.yaml"
  grep -q "end: 0.002" "$work/scenarios/bench_$c.yaml"
done
status=0
for s in "$work"/scenarios/*.yaml; do
  name=$(basename "$s" .yaml)
  [[ "$name" =~ ${SAME_BITS_ONLY:-.} ]] || continue
  for threads in 1 2; do
    for build in a b; do
      dir=$work/$build/$name/t$threads
      mkdir -p "$(dirname "$dir")"
      root=$a
      [ $build = b ] && root=$b
      if ! "$root/bin/talus" run "$s" --threads "$threads" --output-dir "$dir" --force \
          > "$dir.log" 2>&1; then
        echo "same_bits: $name failed with build $build at $threads threads: $dir.log"
        status=1
      elif grep -o '"path": "[^"]*"' "$dir/provenance.json" | grep -v -q "\"$root/"; then
        echo "same_bits: $name with build $build loaded a plugin from outside it:"
        grep -o '"path": "[^"]*"' "$dir/provenance.json" | grep -v "\"$root/"
        status=1
      fi
    done
    if diff -r -q -x provenance.json "$work/a/$name/t$threads" "$work/b/$name/t$threads" > /dev/null
    then
      echo "same   $name ($threads threads, $(find "$work/a/$name/t$threads" -type f | wc -l) files)"
    else
      echo "DIFFER $name ($threads threads):"
      diff -r -q -x provenance.json "$work/a/$name/t$threads" "$work/b/$name/t$threads" |
        head -5 || true
      status=1
    fi
  done
done
exit $status
