"""particles.pvd grows in place: after its first output the collection is
the same file (the same inode) to the end, never rewritten whole and
renamed (which cost the length of every entry at every output: a run of
15,000 outputs slowed 4.6-fold), and it stays a valid collection listing
exactly the VTK files of the rows of diagnostics.csv.

usage: pvd_append.py TALUS_EXE SCENARIO WORK_DIR"""
import glob
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET


def main():
    exe, scenario, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    pvd = os.path.join(work, "particles.pvd")
    p = subprocess.Popen([exe, "run", scenario, "--output-dir", work], stderr=subprocess.PIPE,
                         env=dict(os.environ, OMP_NUM_THREADS="1"), text=True)
    while not os.path.exists(pvd):
        assert p.poll() is None, p.stderr.read()
        time.sleep(0.001)
    p.send_signal(signal.SIGSTOP)
    first = os.stat(pvd).st_ino
    entries_then = len(ET.parse(pvd).getroot().find("Collection"))
    p.send_signal(signal.SIGCONT)
    assert p.wait() == 0, p.stderr.read()

    assert os.stat(pvd).st_ino == first, "particles.pvd was replaced: rewritten whole"
    root = ET.parse(pvd).getroot()
    listed = [d.get("file") for d in root.find("Collection")]
    times = [float(d.get("timestep")) for d in root.find("Collection")]
    with open(os.path.join(work, "diagnostics.csv")) as f:
        rows = [line.split(",") for line in f.read().splitlines()[1:]]
    files = sorted(os.path.basename(f) for f in glob.glob(os.path.join(work, "particles_*.vtu")))
    print(f"{entries_then} entries when first seen, {len(listed)} at the end")
    assert len(listed) > entries_then >= 1
    assert listed == files and len(listed) == len(rows), (len(listed), len(files), len(rows))
    assert times == [float(r[1]) for r in rows], "times differ from diagnostics.csv"
    print("ok")


if __name__ == "__main__":
    main()
