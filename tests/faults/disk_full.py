"""A checkpoint that cannot be written (the disk full, a file-size limit):
the run stops with the file and the system's reason, exit status 1 (not a
crash inside HDF5 at exit, 139), no temporary file left, and the output it
wrote before whole.

usage: disk_full.py TALUS_EXE SCENARIO WORK_DIR

Two ways to fill the disk: a file-size limit (RLIMIT_FSIZE, always), and a
256 kB tmpfs where the test may mount one (as root with the right to)."""
import os
import resource
import shutil
import subprocess
import sys


def run(exe, scenario, out, limit_kb=None):
    def limit():
        if limit_kb:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_kb * 1024, limit_kb * 1024))
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run([exe, "run", scenario, "--output-dir", out], env=env,
                       capture_output=True, text=True, preexec_fn=limit)
    print(f"$ talus run {scenario} --output-dir {out}\n  exit {r.returncode}\n  {r.stderr.strip()}")
    return r


def check(r, out, reason):
    assert r.returncode == 1, f"exit {r.returncode}, not 1"
    assert "bug in Talus" not in r.stderr and "fatal" not in r.stderr, r.stderr
    assert f"checkpoint_0000000005.h5: writing the array" in r.stderr, r.stderr
    assert f"failed: {reason}" in r.stderr, r.stderr
    assert "the run stopped at step 5 (t = " in r.stderr, r.stderr
    left = os.listdir(os.path.join(out, "checkpoints"))
    assert left == [], f"left in checkpoints/: {left}"
    with open(os.path.join(out, "diagnostics.csv")) as f:
        rows = f.read().splitlines()
    assert rows[0].startswith("step,time,") and all(len(x.split(",")) == 17 for x in rows), rows


def main():
    exe, scenario, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    out = os.path.join(work, "limit")
    check(run(exe, scenario, out, limit_kb=64), out, "File too large")

    disk = os.path.join(work, "disk")
    os.makedirs(disk)
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", disk],
                      capture_output=True).returncode != 0:
        print("a full disk: skipped (cannot mount a tmpfs here)")
    else:
        try:
            out = os.path.join(disk, "out")
            check(run(exe, scenario, out), out, "No space left on device")
        finally:
            subprocess.run(["umount", disk])
    print("ok")


if __name__ == "__main__":
    main()
