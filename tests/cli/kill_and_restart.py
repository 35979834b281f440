"""A run killed with SIGKILL at a random moment and continued from its last
checkpoint writes exactly the files of a run never interrupted: every
output file byte for byte (provenance.json, which records the wall-clock
time of its run, and the checkpoints themselves aside).

usage: kill_and_restart.py TALUS_EXE SCENARIO.yaml WORK_DIR THREADS [SEED]"""
import filecmp
import glob
import os
import random
import shutil
import signal
import subprocess
import sys
import time


def run(talus, args, threads, log):
    env = dict(os.environ, OMP_NUM_THREADS=str(threads))
    with open(log, "w") as out:
        return subprocess.Popen([talus, "run"] + args, env=env, stdout=out, stderr=out)


def outputs(folder):
    return sorted(f for f in os.listdir(folder)
                  if f not in ("provenance.json", "checkpoints") and not f.startswith("."))


def main():
    talus, scenario, work, threads = sys.argv[1:5]
    seed = int(sys.argv[5]) if len(sys.argv) > 5 else random.randrange(1 << 30)
    rng = random.Random(seed)
    print(f"seed {seed} (pass it as the fifth argument to repeat this run)")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    full, killed = os.path.join(work, "full"), os.path.join(work, "killed")
    start = time.monotonic()
    p = run(talus, [scenario, "--output-dir", full], threads, os.path.join(work, "full.log"))
    assert p.wait() == 0, open(os.path.join(work, "full.log")).read()
    duration = time.monotonic() - start

    # Kill after the first checkpoint, at a random moment of the rest of the
    # run; a run that ended first is tried again sooner.
    for attempt in range(5):
        shutil.rmtree(killed, ignore_errors=True)
        p = run(talus, [scenario, "--output-dir", killed], threads,
                os.path.join(work, "killed.log"))
        while p.poll() is None and not glob.glob(os.path.join(killed, "checkpoints", "*.h5")):
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.8 * duration) / (attempt + 1))
        if p.poll() is None:
            p.send_signal(signal.SIGKILL)
            assert p.wait() == -signal.SIGKILL
            break
        print(f"attempt {attempt}: the run ended before the kill; again, sooner")
    else:
        sys.exit("the run always ended before it could be killed")
    last = sorted(glob.glob(os.path.join(killed, "checkpoints", "checkpoint_*.h5")))[-1]
    rows = sum(1 for _ in open(os.path.join(killed, "diagnostics.csv")))
    print(f"killed after {rows - 1} output rows; restarting from {os.path.basename(last)}")

    p = run(talus, ["--restart", last], threads, os.path.join(work, "restart.log"))
    assert p.wait() == 0, open(os.path.join(work, "restart.log")).read()
    names = outputs(full)
    assert names == outputs(killed), (names, outputs(killed))
    assert any(n.endswith(".vtu") for n in names) and "stages.csv" in names, names
    _, mismatch, errors = filecmp.cmpfiles(full, killed, names, shallow=False)
    assert not mismatch and not errors, ("files differ", mismatch, errors)
    print(f"{len(names)} files identical ({threads} thread(s))")


if __name__ == "__main__":
    main()
