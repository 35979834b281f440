"""Scenarios of many parts: 100,000 groups read in seconds, not minutes
(the reader was quadratic: 10,000 groups in 2 s, 20,000 in 8 s, 100,000
not done after 120 s); 100,001 stages, each ending in a VTK file, are
counted in the estimate that `talus validate` gives and `talus run`
refuses past 1e5 files (it counted the output times only: 2 files).

usage: reads_many.py TALUS_EXE WORK_DIR"""
import math
import os
import re
import shutil
import subprocess
import sys
import time

# The reader is linear: 100,000 groups take about 6 s on the 2-core CI
# machine (the YAML parser most of it), a quadratic one over 120 s. The
# limit sits between with room both ways.
LIMIT = 60.0

HEAD = """talus: 1
dimension: 2
grid: {{origin: [0, 0], size: [{size}, {size}], cell: 0.5}}
materials:
  m: {{model: linear_elastic, density: 1000, youngs_modulus: 1000, poisson_ratio: 0.3}}
"""


def talus(exe, args):
    t0 = time.monotonic()
    r = subprocess.run([exe] + args, capture_output=True, text=True,
                       env=dict(os.environ, OMP_NUM_THREADS="1"))
    took = time.monotonic() - t0
    print(f"$ talus {' '.join(args)}\n  exit {r.returncode} after {took:.1f} s\n"
          f"  {r.stdout.strip()[:300]}\n  {r.stderr.strip()[:400]}")
    return r, took


def main():
    exe, work = sys.argv[1:3]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)

    n = 100000
    side = math.ceil(math.sqrt(n))
    groups = os.path.join(work, "groups.yaml")
    with open(groups, "w") as f:
        f.write(HEAD.format(size=side + 2) + "groups:\n")
        for k in range(n):
            i, j = k % side, k // side
            f.write(f"  g{k}: {{material: m, shape: {{box: {{min: [{1 + i}, {1 + j}], "
                    f"max: [{2 + i}, {2 + j}]}}}}}}\n")
        f.write("time: {end: 0.01}\n")
    r, took = talus(exe, ["validate", groups])
    assert r.returncode == 0, r.stderr
    assert f"{n} group(s)" in r.stdout, r.stdout
    assert took < LIMIT, f"{n} groups read in {took:.0f} s (limit {LIMIT:.0f} s)"

    stages = os.path.join(work, "stages.yaml")
    m = 100001
    with open(stages, "w") as f:
        f.write(HEAD.format(size=2) + "groups:\n  g: {material: m, shape: {box: "
                "{min: [0.5, 0.5], max: [1.0, 1.0]}}}\nstages:\n")
        for k in range(m):
            f.write(f"  - {{name: s{k}, duration: 1.0e-3}}\n")
    r, took = talus(exe, ["validate", stages])
    assert r.returncode == 0 and took < LIMIT, r.stderr
    files = re.search(r"([0-9.e+]+) VTK files", r.stdout)
    # printed to 3 digits: 1e+05 for the 100,003 files (the start, an
    # output time and each stage end)
    assert files and float(files.group(1)) >= 1e5, r.stdout
    assert re.search(rf"the run would write about [0-9.e+]+ VTK files, more than 1e\+05 "
                     rf"\(one at the end of each of its {m} stage\(s\)\)", r.stderr), r.stderr
    steps = re.search(r"about ([0-9.e+]+) steps", r.stdout)
    assert steps and float(steps.group(1)) >= 1e5, "each stage takes a step at least"
    out = os.path.join(work, "stages_out")
    r, _ = talus(exe, ["run", stages, "--output-dir", out])
    assert r.returncode != 0 and "--allow-large" in r.stderr, r.stderr
    assert not os.path.exists(os.path.join(out, "particles_00000.vtu")), "files written"
    print("ok")


if __name__ == "__main__":
    main()
