"""A value or a key of 2 MB in a scenario: refused at its place in a
message of a few lines, the value clipped (its first 60 characters and
its length), not echoed whole.

usage: huge_value.py TALUS_EXE WORK_DIR"""
import os
import shutil
import subprocess
import sys

BASE = """talus: 1
dimension: 2
grid: {{origin: [0, 0], size: [1, 1], cell: 0.1}}
materials:
  m: {{model: linear_elastic, density: 1000, youngs_modulus: {value}, poisson_ratio: 0.3}}
groups:
  g: {{material: m, shape: {{box: {{min: [0.2, 0.2], max: [0.4, 0.4]}}}}, {key}: 1}}
time: {{end: 0.01}}
"""
HUGE = 2 * 1000 * 1000


def main():
    exe, work = sys.argv[1:3]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    for name, value, key in (("value", "x" * HUGE, "velocity_unused"),
                             ("key", "1.0e6", "k" * HUGE)):
        path = os.path.join(work, name + ".yaml")
        with open(path, "w") as f:
            f.write(BASE.format(value=value, key=key))
        r = subprocess.run([exe, "validate", path], capture_output=True, text=True, timeout=120)
        print(f"{name}: exit {r.returncode}, {len(r.stderr)} characters:\n{r.stderr[:500]}")
        assert r.returncode != 0
        # A key that long is a YAML syntax error already (implicit keys
        # are at most 1024 characters): located and short, as any.
        assert name == "key" or f"({HUGE} characters)" in r.stderr, "the length is not said"
        assert len(r.stderr) < 4000, f"{len(r.stderr)} characters of message"
        assert f"{name}.yaml:{5 if name == 'value' else 7}:" in r.stderr, "not located"
    print("ok")


if __name__ == "__main__":
    main()
