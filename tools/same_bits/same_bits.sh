#!/usr/bin/env bash
# Same bits: runs the identity scenarios with two builds of Talus and
# compares every output file byte for byte (the provenance record, which
# names the build and the time, aside). A change that must not change a
# result (a refactor, a build change) leaves them identical at 1 and 2
# threads.
#   tools/same_bits/same_bits.sh BUILD_A BUILD_B [WORK]
# BUILD_A and BUILD_B are build folders (bin/talus, bin/talus_bench). The
# scenarios: every configs/**/*.yaml, and the benchmark blocks of
# talus_bench (2D and 3D, linear_elastic and mohr_coulomb) cut to a short
# time, so that the whole set runs in minutes.
set -euo pipefail
a=$(cd "$1" && pwd) b=$(cd "$2" && pwd)
work=${3:-$(mktemp -d)}
src=$(cd "$(dirname "$0")/../.." && pwd)
mkdir -p "$work/scenarios"
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
  for threads in 1 2; do
    for build in a b; do
      dir=$work/$build/$name/t$threads
      mkdir -p "$(dirname "$dir")"
      exe=$a/bin/talus
      [ $build = b ] && exe=$b/bin/talus
      "$exe" run "$s" --threads "$threads" --output-dir "$dir" --force > "$dir.log" 2>&1 ||
        { echo "same_bits: $name failed with build $build at $threads threads: $dir.log"; status=1; }
    done
    if diff -r -q -x provenance.json "$work/a/$name/t$threads" "$work/b/$name/t$threads" > /dev/null
    then
      echo "same   $name ($threads threads, $(find "$work/a/$name/t$threads" -type f | wc -l) files)"
    else
      echo "DIFFER $name ($threads threads):"
      diff -r -q -x provenance.json "$work/a/$name/t$threads" "$work/b/$name/t$threads" | head -5
      status=1
    fi
  done
done
exit $status
