"""A FIFO, a device or a directory where Talus expects a file (a scenario, a
driver case, a plugin, a UMAT library, a checkpoint, a reference CSV) is
refused at once, by name; before, a FIFO blocked the reader for ever and
/dev/zero was read until memory ran out.

usage: not_a_file.py TALUS_EXE WORK_DIR"""
import os
import shutil
import subprocess
import sys

LIMIT = 20  # seconds: each call answers in well under one; a hang fails


def refused(exe, args, kind, cwd):
    try:
        r = subprocess.run([exe] + args, cwd=cwd, capture_output=True, text=True,
                           timeout=LIMIT, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        sys.exit(f"talus {' '.join(args)}: no answer after {LIMIT} s (blocked)")
    print(f"$ talus {' '.join(args)}\n  exit {r.returncode}\n  {r.stderr.strip()[:300]}")
    assert r.returncode != 0, r.stderr
    assert f"{kind}, not a file" in r.stderr, f"/{kind}, not a file/ not in:\n{r.stderr}"
    assert "bug in Talus" not in r.stderr, r.stderr


def main():
    exe, work = sys.argv[1:3]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    fifo = os.path.join(work, "fifo.yaml")
    os.mkfifo(fifo)
    os.mkfifo(os.path.join(work, "fifo.so"))
    os.mkfifo(os.path.join(work, "fifo.h5"))
    os.mkfifo(os.path.join(work, "fifo.csv"))
    os.makedirs(os.path.join(work, "folder.yaml"))

    for cmd in (["validate"], ["run"], ["point"]):
        refused(exe, cmd + ["fifo.yaml"], "a FIFO", work)
        refused(exe, cmd + ["folder.yaml"], "a directory", work)
    refused(exe, ["validate", "/dev/zero"], "a character device", work)
    refused(exe, ["plugin", "info", "./fifo.so"], "a FIFO", work)
    refused(exe, ["run", "--restart", "fifo.h5"], "a FIFO", work)

    def case(name, text):
        with open(os.path.join(work, name), "w") as f:
            f.write(text)
    case("plugin.yaml", "talus: 1\ndimension: 2\nplugins: [./fifo.so]\n"
         "grid: {origin: [0, 0], size: [1, 1], cell: 0.1}\n"
         "materials: {m: {model: linear_elastic, density: 1, youngs_modulus: 1, "
         "poisson_ratio: 0.3}}\n"
         "groups: {g: {material: m, shape: {box: {min: [0.2, 0.2], max: [0.4, 0.4]}}}}\n"
         "time: {end: 0.01}\n")
    refused(exe, ["validate", "plugin.yaml"], "a FIFO", work)
    strain = "time: {end: 1.0, increments: 2}\nstrain:\n  xx: [[0, 0], [1, -0.001]]\n"
    case("umat.yaml", "talus: 1\nmaterial: {model: umat, density: 1, library: fifo.so, "
         "props: [2.0e7, 0.3]}\n" + strain)
    refused(exe, ["point", "umat.yaml"], "a FIFO", work)
    case("compare.yaml", "talus: 1\nmaterial: {model: linear_elastic, density: 1, "
         "youngs_modulus: 2.0e7, poisson_ratio: 0.3}\n" + strain +
         "compare: {file: fifo.csv, x: eps_xx, columns: {sig_xx: {column: s, relative: 1e-6}}}\n")
    refused(exe, ["point", "compare.yaml"], "a FIFO", work)
    print("ok")


if __name__ == "__main__":
    main()
