"""`talus run` on several ranks (docs/mpi.md) as a user runs it, under
mpirun, checked against the same scenario run on one rank without MPI:

1. On 3 ranks: the output is a .pvtu per output time with one piece per
   rank, read back by VTK's own parallel reader (the one ParaView uses);
   every frame holds every particle once; the CSV rows and the last frame's
   particles (matched by id) equal the one-rank run's to round-off.
2. Stopped by SIGTERM sent to one of its ranks after its first checkpoint
   (all ranks agree to stop at the same step), and continued from the
   checkpoint it wrote on 3 ranks: every output file equals the uninterrupted 3-rank run's, byte for
   byte (pieces included).
   A rank's file missing, or a rank's file given instead of rank 0's, is
   refused with one message.
3. The same checkpoint continued on 2 ranks and on 1 (another number of
   ranks: the particles are spread anew): the results equal the
   uninterrupted run's to round-off.
4. The scenario has two stages (the first ends when the slope is at rest,
   the second switches its material and adds a group): the stop in 2. lies
   in the first, so the restarts cross the stage change; the uninterrupted
   run's checkpoint in the second stage, continued on 3 ranks, gives every
   output file byte for byte, and on 2 ranks to round-off. stages.csv is
   compared as the other CSV files.
5. The one-rank run's checkpoint in the second stage continued on 3 ranks
   (one file for three ranks: rank 0 reads it, the particles go to their
   cells' ranks) equals the one-rank run to round-off.

Round-off: the runs differ only in the order in which each shared node's
terms are added (and, after a restart on another number of ranks, the
particles' order), each such sum within about 1e-15 relative. Over the run's
steps this accumulates to at most about 1e-15 x steps of each quantity's
scale; the tolerance is 10 times that bound (measured: about 3e-15 x scale).

usage: run_on_ranks.py TALUS_EXE MPIEXEC SCENARIO.yaml WORK_DIR"""
import csv
import filecmp
import glob
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import vtk


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def mpi(mpiexec, ranks):
    # --oversubscribe: more ranks than cores; root in CI's container.
    return [mpiexec, "--oversubscribe", "--allow-run-as-root", "-np", str(ranks),
            "-x", "OMP_NUM_THREADS=1"]


def run(cmd, log):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    with open(log, "w") as out:
        return subprocess.Popen(cmd, env=env, stdout=out, stderr=out)


def must(cmd, log):
    p = run(cmd, log)
    if p.wait() != 0:
        fail(f"{' '.join(cmd)} exited with {p.returncode}:\n{open(log).read()}")
    return open(log).read()


def talus_processes(parent):
    """The talus processes descending from `parent` (the ranks mpirun
    started), by /proc."""
    children = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            stat = open(f"/proc/{d}/stat").read()
        except OSError:
            continue
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        ppid = int(stat[stat.rindex(")") + 2:].split()[1])
        children.setdefault(ppid, []).append((int(d), name))
    found, todo = [], [parent]
    while todo:
        for pid, name in children.get(todo.pop(), []):
            todo.append(pid)
            if name == "talus":
                found.append(pid)
    return sorted(found)


def rows(folder, name):
    return list(csv.DictReader(open(os.path.join(folder, name))))


def frames(folder):
    text = open(os.path.join(folder, "particles.pvd")).read()
    return re.findall(r'timestep="([^"]+)" part="0" file="([^"]+)"', text)


def read(folder, file):
    """Particles of one output file by id: position, velocity, stress."""
    parallel = file.endswith(".pvtu")
    reader = vtk.vtkXMLPUnstructuredGridReader() if parallel else vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(os.path.join(folder, file))
    reader.Update()
    grid = reader.GetOutput()
    pd = grid.GetPointData()
    ids, vel, sig = pd.GetArray("id"), pd.GetArray("velocity"), pd.GetArray("stress")
    if ids is None or vel is None or sig is None:
        fail(f"{folder}/{file}: missing arrays")
    out = {}
    for i in range(grid.GetNumberOfPoints()):
        k = int(ids.GetValue(i))
        if k in out:
            fail(f"{folder}/{file}: particle {k} twice")
        out[k] = (grid.GetPoint(i), vel.GetTuple3(i), sig.GetTuple9(i))
    return out


def close(a, b, steps, what):
    """Every number of `a` and `b` within 10 x 1e-15 x steps x its scale."""
    for key in ("position", "velocity", "stress"):
        j = ("position", "velocity", "stress").index(key)
        scale = max(abs(x) for p in a.values() for x in p[j]) + 1e-300
        tol = 10 * 1e-15 * steps * scale
        worst = max(abs(x - y) for k in a for x, y in zip(a[k][j], b[k][j]))
        if worst > tol:
            fail(f"{what}: {key} differs by {worst:.3g}, above {tol:.3g}")
        print(f"{what}: {key} within {worst:.2g} (tolerance {tol:.2g})")


def number(text):
    try:
        return float(text)
    except ValueError:
        return None


def csv_close(a, b, steps, what):
    """Counts, steps and names equal; NaN (a probe of an absent group, the
    rest ratio of a stage without a rest test) where the other has NaN;
    other numbers within 10 x 1e-15 x steps x the column's scale."""
    if len(a) != len(b):
        fail(f"{what}: {len(a)} rows against {len(b)}")
    for key in a[0]:
        xs = [number(x[key]) for x in a]
        exact = key in ("step", "particles", "removed", "cut_steps", "held_at_faces", "stage",
                        "first_step", "last_step", "last_output")
        if exact or None in xs:
            if any(x[key] != y[key] for x, y in zip(a, b)):
                fail(f"{what}: column {key} differs")
            continue
        ys = [number(y[key]) for y in b]
        if None in ys or any(math.isnan(x) != math.isnan(y) for x, y in zip(xs, ys)):
            fail(f"{what}: column {key}: NaN or text where the other has a number")
        pairs = [(x, y) for x, y in zip(xs, ys) if not math.isnan(x)]
        if not pairs:
            continue
        scale = max(abs(x) for x, _ in pairs) + 1e-300
        worst = max(abs(x - y) for x, y in pairs)
        if worst > 10 * 1e-15 * steps * scale:
            fail(f"{what}: column {key} differs by {worst:.3g} (scale {scale:.3g})")


def outputs(folder):
    """Every output file, pieces included, but provenance.json (it records
    its run's wall-clock time) and the checkpoints."""
    found = []
    for root, dirs, files in os.walk(folder):
        dirs[:] = [d for d in dirs if d != "checkpoints"]
        for f in files:
            if f != "provenance.json" and not f.startswith("."):
                found.append(os.path.relpath(os.path.join(root, f), folder))
    return sorted(found)


def main():
    talus, mpiexec, scenario, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    one, three = os.path.join(work, "one"), os.path.join(work, "three")
    must([talus, "run", scenario, "--output-dir", one], os.path.join(work, "one.log"))
    log = must(mpi(mpiexec, 3) + [talus, "run", scenario, "--output-dir", three],
               os.path.join(work, "three.log"))
    if "on 3 ranks" not in log:
        fail(f"the log does not say the run is on 3 ranks:\n{log}")

    # 1. The parallel files, read by VTK, against the one-rank run.
    f3, f1 = frames(three), frames(one)
    if len(f3) != len(f1) or any(not f.endswith(".pvtu") for _, f in f3):
        fail(f"frames: {f3} against {f1}")
    for _, f in f3:
        pieces = glob.glob(os.path.join(three, f[:-len(".pvtu")], "rank_*.vtu"))
        if len(pieces) != 3:
            fail(f"{f}: {len(pieces)} pieces")
    steps = int(rows(one, "diagnostics.csv")[-1]["step"])
    for (t3, a), (t1, b) in zip(f3, f1):
        p3, p1 = read(three, a), read(one, b)
        if set(p3) != set(p1):
            fail(f"{a}: {len(p3)} particles, the one-rank run {len(p1)}")
    close(read(one, f1[-1][1]), read(three, f3[-1][1]), steps, "3 ranks against 1")
    for name in ("diagnostics.csv", "probes.csv", "stages.csv"):
        csv_close(rows(one, name), rows(three, name), steps, f"{name}, 3 ranks against 1")

    # 2. SIGTERM after the first checkpoint, then a restart on 3 ranks.
    stopped = os.path.join(work, "stopped")
    for attempt in range(5):
        shutil.rmtree(stopped, ignore_errors=True)
        p = run(mpi(mpiexec, 3) + [talus, "run", scenario, "--output-dir", stopped],
                os.path.join(work, "stopped.log"))
        while p.poll() is None and not glob.glob(os.path.join(stopped, "checkpoints", "*.h5")):
            time.sleep(0.005)
        if p.poll() is None:
            # To one rank only (mpirun passes a signal on only after about a
            # second): the ranks agree to stop at the same step's end.
            ranks = talus_processes(p.pid)
            if len(ranks) != 3:
                fail(f"found {len(ranks)} talus processes under mpirun")
            os.kill(ranks[-1], signal.SIGTERM)
            p.wait()
            break
        print(f"attempt {attempt}: the run ended before the signal; again")
    else:
        fail("the run always ended before it could be stopped")
    log = open(os.path.join(work, "stopped.log")).read()
    m = re.search(r"talus run --restart (\S+\.h5)", log)
    if not m or "stopped by SIGTERM" not in log:
        fail(f"no restart command in the stopped run's log:\n{log}")
    checkpoint = m.group(1)
    print(next(line for line in log.splitlines() if "stopped by SIGTERM" in line))
    copies = {}
    for ranks in (2, 1):
        copies[ranks] = os.path.join(work, f"restart_on_{ranks}")
        shutil.copytree(stopped, copies[ranks])
    # A checkpoint with a rank's file missing, or a rank's file named
    # instead of rank 0's: refused with one message, and nothing written.
    broken = os.path.join(work, "broken")
    shutil.copytree(stopped, broken)
    head = os.path.join(broken, "checkpoints", os.path.basename(checkpoint))
    part = head[:-len(".h5")] + ".rank0001.h5"
    refusals = ((head, part, f"{part}: missing"),
                (part, None, "restart from rank 0's file"))
    for given, remove, expected in refusals:
        if remove:
            os.rename(remove, remove + ".away")
        p = run(mpi(mpiexec, 3) + [talus, "run", "--restart", given],
                os.path.join(work, "broken.log"))
        code = p.wait()
        log = open(os.path.join(work, "broken.log")).read()
        if code == 0 or log.count(expected) != 1:
            fail(f"restart from {given}: exit {code}, expected one '{expected}':\n{log}")
        if remove:
            os.rename(remove + ".away", remove)
    if outputs(broken) != outputs(stopped):
        fail("a refused restart changed the output folder")

    must(mpi(mpiexec, 3) + [talus, "run", "--restart", checkpoint],
         os.path.join(work, "restart3.log"))
    names = outputs(three)
    if names != outputs(stopped):
        fail(f"files: {names} against {outputs(stopped)}")
    _, mismatch, errors = filecmp.cmpfiles(three, stopped, names, shallow=False)
    if mismatch or errors:
        fail(f"restarted on 3 ranks: files differ: {mismatch} {errors}")
    print(f"restarted on 3 ranks: {len(names)} files identical")

    # 3. The same checkpoint on 2 ranks and on 1.
    for ranks, folder in copies.items():
        cp = os.path.join(folder, "checkpoints", os.path.basename(checkpoint))
        launch = mpi(mpiexec, ranks) if ranks > 1 else []
        must(launch + [talus, "run", "--restart", cp], os.path.join(work, f"restart{ranks}.log"))
        fr = frames(folder)
        if len(fr) != len(f3):
            fail(f"restarted on {ranks}: {len(fr)} frames, {len(f3)} expected")
        close(read(three, f3[-1][1]), read(folder, fr[-1][1]), steps,
              f"restarted on {ranks} rank(s) against 3")
        for name in ("diagnostics.csv", "probes.csv", "stages.csv"):
            csv_close(rows(three, name), rows(folder, name), steps,
                      f"{name}, restarted on {ranks} rank(s) against 3")

    # 4. From the uninterrupted run's second-last checkpoint, in the last
    # stage (the berm generated on every rank and kept by its cells' ranks,
    # the slope switched to its weak material): on 3 ranks byte for byte, on
    # 2 to round-off.
    late = sorted(glob.glob(os.path.join(three, "checkpoints", "checkpoint_??????????.h5")))
    if len(late) != 2:
        fail(f"the uninterrupted run kept {len(late)} checkpoints, not 2")
    first_stage_end = int(rows(three, "stages.csv")[0]["last_step"])
    late_step = int(re.search(r"_(\d+)\.h5$", late[0]).group(1))
    if late_step <= first_stage_end:
        fail(f"checkpoint {late[0]} is not in the last stage (from step {first_stage_end + 1})")
    for ranks in (3, 2):
        folder = os.path.join(work, f"late_on_{ranks}")
        shutil.copytree(three, folder)
        cp = os.path.join(folder, "checkpoints", os.path.basename(late[0]))
        must(mpi(mpiexec, ranks) + [talus, "run", "--restart", cp],
             os.path.join(work, f"late{ranks}.log"))
        if ranks == 3:
            _, mismatch, errors = filecmp.cmpfiles(three, folder, names, shallow=False)
            if mismatch or errors or outputs(folder) != names:
                fail(f"restarted in the last stage on 3 ranks: files differ: {mismatch} {errors}")
            print(f"restarted in the last stage on 3 ranks: {len(names)} files identical")
        else:
            fr = frames(folder)
            close(read(three, f3[-1][1]), read(folder, fr[-1][1]), steps,
                  "restarted in the last stage on 2 ranks against 3")
            for name in ("diagnostics.csv", "probes.csv", "stages.csv"):
                csv_close(rows(three, name), rows(folder, name), steps,
                          f"{name}, restarted in the last stage on 2 ranks against 3")

    # 5. The one-rank run's second-last checkpoint on 3 ranks: one file,
    # read by rank 0 alone, its particles sent to the other ranks' cells.
    late = sorted(glob.glob(os.path.join(one, "checkpoints", "checkpoint_*.h5")))
    folder = os.path.join(work, "one_on_3")
    shutil.copytree(one, folder)
    cp = os.path.join(folder, "checkpoints", os.path.basename(late[0]))
    must(mpi(mpiexec, 3) + [talus, "run", "--restart", cp], os.path.join(work, "one_on_3.log"))
    fr = frames(folder)
    if not fr[-1][1].endswith(".pvtu"):
        fail(f"the one-rank checkpoint continued on 3 ranks wrote {fr[-1][1]}")
    close(read(one, f1[-1][1]), read(folder, fr[-1][1]), steps,
          "the one-rank checkpoint continued on 3 ranks against one rank")
    for name in ("diagnostics.csv", "probes.csv", "stages.csv"):
        csv_close(rows(one, name), rows(folder, name), steps,
                  f"{name}, the one-rank checkpoint continued on 3 ranks against one rank")
    print("all checks passed")


if __name__ == "__main__":
    main()
