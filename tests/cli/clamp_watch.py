"""Material torn off a clamp is said, with where and when: the CPDI
cantilever (configs/verification/cantilever_self_weight.yaml) with
quadratic B-splines tears off its clamp between 0.5 and 1.1 s (its
comment), and the run says so once, at the face x-, by 0.6 s; with the
gimp kernel, where it stays clamped (the verification test follows the
finite element run), nothing is said.

usage: clamp_watch.py TALUS_EXE CONFIG_DIR WORK_DIR"""
import os
import re
import shutil
import subprocess
import sys


def main():
    exe, configs, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    with open(os.path.join(configs, "verification", "cantilever_self_weight.yaml")) as f:
        text = f.read().replace("time: {end: 3}", "time: {end: 0.6}")
    for shape, torn in (("bspline2", True), ("gimp", False)):
        case = os.path.join(work, shape + ".yaml")
        with open(case, "w") as f:
            f.write(text.replace("shape: gimp", "shape: " + shape))
        r = subprocess.run([exe, "run", case, "--output-dir", os.path.join(work, shape)],
                           capture_output=True, text=True)
        print(f"{shape}: exit {r.returncode}\n{r.stderr}")
        assert r.returncode == 0, r.stderr
        said = re.findall(r"talus: warning: step \d+ \(t = ([0-9.]+) s\): \d+ particle\(s\) that "
                          r"began within h/4 of the fixed face x- have moved more than h/2 "
                          r"\(up to [0-9.e-]+ m; particle \d+ of group 'beam'", r.stderr)
        if torn:
            assert len(said) == 1 and 0.3 < float(said[0]) <= 0.6, said
        else:
            assert not said and "fixed face" not in r.stderr, r.stderr
    print("ok")


if __name__ == "__main__":
    main()
