"""A UMAT library named without a folder is the file beside the input file,
never one of the same name that LD_LIBRARY_PATH or the system's folders
hold (docs/umat.md).

usage: umat_library.py TALUS_EXE UMAT.so IMPOSTOR.so WORK_DIR

IMPOSTOR.so is any shared library without the UMAT's symbol: loaded
instead, the run fails with "exports no symbol"."""
import os
import shutil
import subprocess
import sys

CASE = """talus: 1
material: {model: umat, density: 1800, library: elastic_umat.so, props: [2.0e7, 0.3]}
time: {end: 1.0, increments: 10}
strain:
  xx: [[0, 0], [1, -0.001]]
"""


def point(exe, folder, path_dir):
    env = dict(os.environ, OMP_NUM_THREADS="1", LD_LIBRARY_PATH=path_dir)
    r = subprocess.run([exe, "point", "case.yaml", "-o", "out.csv"], cwd=folder, env=env,
                       capture_output=True, text=True)
    print(f"$ (cd {folder}; LD_LIBRARY_PATH={path_dir} talus point case.yaml)\n"
          f"  exit {r.returncode}\n  {r.stderr.strip()}")
    return r


def main():
    exe, umat, impostor, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    beside, elsewhere = os.path.join(work, "beside"), os.path.join(work, "path")
    os.makedirs(beside)
    os.makedirs(elsewhere)
    shutil.copy(impostor, os.path.join(elsewhere, "elastic_umat.so"))
    with open(os.path.join(beside, "case.yaml"), "w") as f:
        f.write(CASE)

    # Beside the case: that one, whatever the search path holds.
    shutil.copy(umat, os.path.join(beside, "elastic_umat.so"))
    r = point(exe, beside, elsewhere)
    assert r.returncode == 0, r.stderr
    last = open(os.path.join(beside, "out.csv")).read().splitlines()[-1]
    print(f"  last row: {last[:120]}")

    # Not beside it: refused, naming the file beside it, not the impostor.
    os.remove(os.path.join(beside, "elastic_umat.so"))
    os.remove(os.path.join(beside, "out.csv"))
    r = point(exe, beside, elsewhere)
    assert r.returncode != 0, r.stderr
    want = f"cannot load the UMAT library '{os.path.realpath(beside)}/elastic_umat.so'"
    assert want in r.stderr or want.replace(os.path.realpath(beside), beside) in r.stderr, r.stderr
    assert "exports no symbol" not in r.stderr, r.stderr
    print("ok")


if __name__ == "__main__":
    main()
