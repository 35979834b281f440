"""Faults of the output folder: a folder never mixes the files of two runs.

usage: output_folder.py CASE TALUS_EXE DATA_DIR WORK_DIR

CASE is one of
  foreign_restart   a restart with another run's checkpoint, or another
                    scenario's, into an existing run's folder is refused and
                    leaves the folder as it was; into its own folder it goes on
  busy_folder       a second run into a folder another run is writing is
                    refused, naming the first run's PID; the first run's files
                    stay whole; once it has ended (or was killed) a run goes in
  checkpoints_link  checkpoints/ a symbolic link to a folder holding
                    checkpoints: a new run, --force or not, leaves them there
                    and refuses; to an empty folder it goes in and writes there
  restart_again     a restart keeps the checkpoint it started from, however
                    many it writes after it (keep: 2), so the same command
                    continues the run again, to the same files; its summary
                    says which counts are of its own part
"""
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import time


def talus(exe, args, log=None):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run([exe] + args, env=env, capture_output=True, text=True)
    if log:
        print(f"$ talus {' '.join(args)}\n  exit {r.returncode}\n  {r.stderr.strip()[-600:]}")
    return r


def run_ok(exe, args):
    r = talus(exe, args)
    assert r.returncode == 0, f"talus {' '.join(args)}: exit {r.returncode}\n{r.stderr}"


def state(folder):
    """Every file under the folder with its bytes and modification time."""
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            with open(p, "rb") as fh:
                out[os.path.relpath(p, folder)] = (fh.read(), os.stat(p).st_mtime_ns)
    return out


def last_checkpoint(folder):
    return sorted(glob.glob(os.path.join(folder, "checkpoints", "checkpoint_*.h5")))[-1]


def refused(exe, args, folder, pattern):
    """The restart is refused with `pattern` in its message and leaves
    `folder` byte for byte and time for time as it was."""
    before = state(folder)
    r = talus(exe, args, log=True)
    assert r.returncode != 0, f"accepted: talus {' '.join(args)}\n{r.stderr}"
    assert re.search(pattern, r.stderr), f"message lacks /{pattern}/:\n{r.stderr}"
    assert "bug in Talus" not in r.stderr, r.stderr
    after = state(folder)
    assert before == after, (
        f"{folder} changed: "
        f"{sorted(set(before) ^ set(after)) or [k for k in before if before[k] != after[k]]}")


def foreign_restart(exe, data, work):
    a, a2, b = (os.path.join(work, n) for n in ("a", "a_again", "b"))
    scenario = os.path.join(data, "checkpointed.yaml")
    other = os.path.join(data, "checkpointed_other.yaml")
    run_ok(exe, ["run", scenario, "--output-dir", a])
    run_ok(exe, ["run", scenario, "--output-dir", a2])
    run_ok(exe, ["run", other, "--output-dir", b])

    # Another run of the same scenario: only the run's name tells them apart.
    refused(exe, ["run", "--restart", last_checkpoint(a), "--output-dir", a2], a2,
            r"not the folder of the checkpoint's run: it holds run [0-9a-f]{32}")
    # Another scenario's run.
    refused(exe, ["run", "--restart", last_checkpoint(b), "--output-dir", a], a,
            r"not the folder of the checkpoint's run: it holds run")
    # A folder of a Talus that named no runs: the scenario's digest decides.
    prov = os.path.join(a2, "provenance.json")
    with open(prov) as f:
        text = f.read()
    assert '"run_id"' in text, text
    with open(prov, "w") as f:
        f.write(re.sub(r'\s*"run_id": "[0-9a-f]*",', "", text))
    refused(exe, ["run", "--restart", last_checkpoint(b), "--output-dir", a2], a2,
            r"it holds a run of .*checkpointed\.yaml \(scenario SHA-256")
    # A run's files without the record of whose they are.
    os.remove(prov)
    refused(exe, ["run", "--restart", last_checkpoint(a), "--output-dir", a2], a2,
            r"it holds a run's files \(.*\) but no provenance\.json")

    # Its own folder: the run goes on, as before.
    r = talus(exe, ["run", "--restart", last_checkpoint(a)], log=True)
    assert r.returncode == 0, r.stderr


def wait_for(path, p, what):
    t0 = time.monotonic()
    while not os.path.exists(path):
        assert p.poll() is None, f"{what} ended before writing {path}"
        assert time.monotonic() - t0 < 120, f"{what}: no {path} after 120 s"
        time.sleep(0.005)


def whole(folder):
    """The run's files agree: a VTK file per output row, each in the .pvd."""
    with open(os.path.join(folder, "diagnostics.csv")) as f:
        rows = sum(1 for _ in f) - 1
    with open(os.path.join(folder, "particles.pvd")) as f:
        listed = re.findall(r'file="([^"]+)"', f.read())
    files = sorted(os.path.basename(p) for p in glob.glob(os.path.join(folder, "particles_*.vtu")))
    assert rows == len(listed) == len(files) and sorted(listed) == files, (rows, listed, files)
    return rows


def busy_folder(exe, data, work):
    folder = os.path.join(work, "shared")
    scenario = os.path.join(data, "checkpointed.yaml")
    env = dict(os.environ, OMP_NUM_THREADS="1")
    log = open(os.path.join(work, "first.log"), "w")
    first = subprocess.Popen([exe, "run", scenario, "--output-dir", folder], env=env,
                             stdout=log, stderr=log)
    # Held still while it writes (SIGSTOP), so that the second run surely
    # comes while the first one holds the folder.
    wait_for(os.path.join(folder, "diagnostics.csv"), first, "the first run")
    first.send_signal(signal.SIGSTOP)
    try:
        r = talus(exe, ["run", scenario, "--output-dir", folder, "--force"], log=True)
        assert r.returncode != 0, f"a second run went into a busy folder:\n{r.stderr}"
        assert re.search(rf"^talus: error: .*another run is writing into this folder: talus, "
                         rf"PID {first.pid} ", r.stderr, re.M), r.stderr
        assert "choose another --output-dir" in r.stderr, r.stderr
        # A restart into it too.
        ck = os.path.join(work, "elsewhere")
        run_ok(exe, ["run", scenario, "--output-dir", ck])
        r = talus(exe, ["run", "--restart", last_checkpoint(ck), "--output-dir", folder],
                  log=True)
        assert r.returncode != 0 and f"PID {first.pid} " in r.stderr, r.stderr
        # A restart has its run's folder only: no advice to go elsewhere.
        assert "was not continued" in r.stderr and "--output-dir" not in r.stderr, r.stderr
    finally:
        first.send_signal(signal.SIGCONT)
    assert first.wait() == 0, open(os.path.join(work, "first.log")).read()
    rows = whole(folder)
    assert rows == 5, f"{rows} output rows, not the 5 of t = 0, 0.05, ..., 0.2"
    assert not os.path.exists(os.path.join(folder, ".talus.lock")), "the lock file stayed"

    # A run that ended, however it ended, holds nothing: one killed while
    # it held the folder leaves the lock file, not the lock.
    for attempt in range(10):
        log = open(os.path.join(work, "killed.log"), "w")
        killed = subprocess.Popen([exe, "run", scenario, "--output-dir", folder, "--force"],
                                  env=env, stdout=log, stderr=log)
        wait_for(os.path.join(folder, ".talus.lock"), killed, "the run to be killed")
        killed.send_signal(signal.SIGKILL)
        if killed.wait() == -signal.SIGKILL and os.path.exists(
                os.path.join(folder, ".talus.lock")):
            break
    else:
        sys.exit("the run always ended before it could be killed")
    run_ok(exe, ["run", scenario, "--output-dir", folder, "--force"])
    assert whole(folder) == 5


def checkpoints_link(exe, data, work):
    scenario = os.path.join(data, "checkpointed.yaml")
    out, scratch = os.path.join(work, "out"), os.path.join(work, "scratch")
    run_ok(exe, ["run", scenario, "--output-dir", out])
    shutil.move(os.path.join(out, "checkpoints"), scratch)
    os.symlink(scratch, os.path.join(out, "checkpoints"))
    kept = sorted(os.listdir(scratch))
    assert kept, "no checkpoints to keep"
    for force in ([], ["--force"]):
        r = talus(exe, ["run", scenario, "--output-dir", out] + force, log=True)
        assert r.returncode != 0 and "a symbolic link" in r.stderr, r.stderr
        assert sorted(os.listdir(scratch)) == kept, "checkpoints removed through the link"
    for f in kept:
        os.remove(os.path.join(scratch, f))
    run_ok(exe, ["run", scenario, "--output-dir", out, "--force"])
    assert os.listdir(scratch), "the run's checkpoints are not in the linked folder"


def outputs(folder):
    """The run's output files by name (provenance.json records wall time)."""
    out = {}
    for f in sorted(os.listdir(folder)):
        p = os.path.join(folder, f)
        if os.path.isfile(p) and f != "provenance.json" and not f.startswith("."):
            with open(p, "rb") as fh:
                out[f] = fh.read()
    return out


def restart_again(exe, data, work):
    folder = os.path.join(work, "run")
    scenario = os.path.join(data, "checkpointed.yaml")
    env = dict(os.environ, OMP_NUM_THREADS="1")
    # Stopped once its first checkpoint is there, then killed: the run's
    # folder holds one of step 4 or 8 of 18, so that a restart from it
    # writes two or more (every 4 steps) and keep: 2 would prune it.
    first = None
    for attempt in range(10):
        shutil.rmtree(folder, ignore_errors=True)
        log = open(os.path.join(work, "first.log"), "w")
        p = subprocess.Popen([exe, "run", scenario, "--output-dir", folder], env=env,
                             stdout=log, stderr=log)
        while p.poll() is None and not glob.glob(os.path.join(folder, "checkpoints", "*.h5")):
            time.sleep(0.001)
        p.send_signal(signal.SIGSTOP)
        found = sorted(glob.glob(os.path.join(folder, "checkpoints", "checkpoint_*.h5")))
        p.send_signal(signal.SIGKILL)
        p.wait()
        if found and int(re.search(r"_(\d+)\.h5$", found[0]).group(1)) <= 8:
            first = found[0]
            break
    assert first, "no early checkpoint in 10 tries"
    print(f"restarting from {os.path.basename(first)}")
    results = []
    for k in range(2):
        r = talus(exe, ["run", "--restart", first], log=True)
        assert r.returncode == 0, f"restart {k + 1}: exit {r.returncode}\n{r.stderr}"
        assert os.path.exists(first), f"restart {k + 1} removed the checkpoint it started from"
        kept = glob.glob(os.path.join(folder, "checkpoints", "checkpoint_*.h5"))
        assert len(kept) == 3, f"keep: 2 and the start one, not {sorted(kept)}"
        step = int(re.search(r"_(\d+)\.h5$", first).group(1))
        assert re.search(rf"continued from step {step} to step \d+ .* output\(s\) and \d+ "
                         r"checkpoint\(s\) written by this part, 5 output\(s\) of the run",
                         r.stderr), r.stderr
        results.append(outputs(folder))
    assert results[0] == results[1], "the second restart wrote other files"
    assert len(results[0]) >= 4, sorted(results[0])


def main():
    case, exe, data, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    {"foreign_restart": foreign_restart, "busy_folder": busy_folder,
     "checkpoints_link": checkpoints_link, "restart_again": restart_again}[case](exe, data, work)
    print("ok")


if __name__ == "__main__":
    main()
