"""Names with a comma, a double quote or a line break in probes.csv and
stages.csv: every row parses (RFC 4180, Python's csv module) to as many
fields as the header, and the names come back whole.

usage: csv_names.py TALUS_EXE SCENARIO WORK_DIR"""
import csv
import os
import shutil
import subprocess
import sys


def rows(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def main():
    exe, scenario, work = sys.argv[1:4]
    shutil.rmtree(work, ignore_errors=True)
    r = subprocess.run([exe, "run", scenario, "--output-dir", work], capture_output=True,
                       text=True, env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert r.returncode == 0, r.stderr

    probes = rows(os.path.join(work, "probes.csv"))
    head = probes[0]
    assert all(len(row) == len(head) for row in probes), [len(x) for x in probes]
    # time, then 2 + 2 + 2 + 6 columns of the particle probe, 2 + 2 of the other
    assert len(head) == 1 + 12 + 4, head
    assert head[1] == 'tip, "left".x' and head[13] == "centre\nof mass.x", head
    for row in probes[1:]:
        [float(v) for v in row]  # every field a number: no name spilt into them

    stages = rows(os.path.join(work, "stages.csv"))
    assert all(len(row) == len(stages[0]) for row in stages), stages
    assert [row[1] for row in stages[1:]] == ['move, "then"\nstop', "plain"], stages
    print("ok")


if __name__ == "__main__":
    main()
