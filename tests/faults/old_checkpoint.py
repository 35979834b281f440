"""A checkpoint of format 4 as the build of 673afb1 wrote it (no run id;
tests/faults/data/format4_run/, made from format4_run.yaml) restarts in
its folder and ends with the files of an uninterrupted run by this build:
diagnostics.csv byte for byte. --force-restart, since the plugin file of
that build is not this one's. Byte for byte holds for a build of the
same arithmetic as the one that wrote it (the release presets); the
sanitizer build's kernels round differently, so the sanitizer tier leaves
this test out (CMakePresets.json).

usage: old_checkpoint.py TALUS_EXE DATA_DIR WORK_DIR"""
import filecmp
import os
import shutil
import subprocess
import sys


def talus(exe, args):
    r = subprocess.run([exe] + args, capture_output=True, text=True,
                       env=dict(os.environ, OMP_NUM_THREADS="1"))
    print(f"$ talus {' '.join(args)}\n  exit {r.returncode}\n  {r.stderr.strip()[-700:]}")
    return r


def main():
    exe, data, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    old = os.path.join(work, "old")
    shutil.copytree(os.path.join(data, "format4_run"), old)
    r = talus(exe, ["run", "--restart", os.path.join(old, "checkpoints",
                                                      "checkpoint_0000000030.h5"),
                    "--force-restart"])
    assert r.returncode == 0, r.stderr
    assert "continuing from step 30" in r.stderr, r.stderr

    fresh = os.path.join(work, "fresh")
    r = talus(exe, ["run", os.path.join(data, "format4_run.yaml"), "--output-dir", fresh])
    assert r.returncode == 0, r.stderr
    assert filecmp.cmp(os.path.join(old, "diagnostics.csv"),
                       os.path.join(fresh, "diagnostics.csv"), shallow=False), \
        "the restarted run's diagnostics.csv differs from the uninterrupted run's"
    print("ok")


if __name__ == "__main__":
    main()
