"""Faults of a plugin that misbehaves inside the talus process.

usage: misbehaving_plugin.py CASE TALUS_EXE FIXTURE_DIR WORK_DIR

CASE is one of
  fp_environment  a plugin that sets upward rounding in create, or
                  flush-to-zero as it loads: the run's results are those of a
                  well-behaved plugin with the same arithmetic, bit for bit,
                  and the log names the plugin and what it changed
  exit            a plugin that calls exit(0) inside update: `talus run` and
                  `talus point` exit non-zero, name the plugin (and in a run
                  the material, group and step) and the run writes the state
  crash_after     a crash outside any plugin call after a plugin has run (a
                  plugin's write past its arrays crashes the host later):
                  the report names the last plugin called as a possible
                  cause beside a bug in Talus
  one_particle    a plugin that crashes, or calls exit(3), on one particle's
                  input (id 10) in a batch of many: the report names that
                  particle, found by running the batch's points alone
  hangs           a plugin call that never returns, and the run is sent
                  SIGINT: it says at once that it stops when the step ends,
                  10 s later that the step has not and which call it waits
                  for; a second SIGINT ends it
"""
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import time

# Two elastic disks that collide, every arithmetic path of the step
# (the fixtures' elastic update is the same code in all of them).
SCENARIO = """talus: 1
dimension: 2
plugins: [{library}]
grid: {{origin: [0, 0], size: [1.0, 1.0], cell: 0.05}}
materials:
  elastic: {{model: {model}, density: 1000, youngs_modulus: 1.0e4, poisson_ratio: 0.3}}
groups:
  lower: {{material: elastic, shape: {{sphere: {{center: [0.3, 0.3], radius: 0.2}}}}, velocity: [0.5, 0.5]}}
  upper: {{material: elastic, shape: {{sphere: {{center: [0.7, 0.7], radius: 0.2}}}}, velocity: [-0.5, -0.5]}}
solver: {{scheme: usl, transfer: flip, shape: bspline2}}
time: {{end: 0.2}}
output:
  every: 0.02
  probes:
    - {{name: centre, particle: [0.3, 0.3]}}
"""

POINT = """talus: 1
plugins: [{library}]
material: {{model: {model}, density: 1000, youngs_modulus: 1.0e7, poisson_ratio: 0.3}}
time: {{end: 1.0, increments: 20}}
strain:
  xx: [[0, 0], [1, -0.01]]
"""


def talus(exe, fixtures, args):
    env = dict(os.environ, OMP_NUM_THREADS="1")
    r = subprocess.run([exe, "--plugin-path", fixtures] + args, env=env, capture_output=True,
                       text=True)
    print(f"$ talus {' '.join(args)}\n  exit {r.returncode}\n  {r.stderr.strip()[-900:]}")
    return r


def run(exe, fixtures, work, name, library, model):
    scenario = os.path.join(work, name + ".yaml")
    with open(scenario, "w") as f:
        f.write(SCENARIO.format(library=library, model=model))
    out = os.path.join(work, name)
    return talus(exe, fixtures, ["run", scenario, "--output-dir", out]), out


def results(folder):
    texts = {}
    for f in ("diagnostics.csv", "probes.csv"):
        with open(os.path.join(folder, f)) as fh:
            texts[f] = fh.read()
    return texts


def fp_environment(exe, fixtures, work):
    r, good = run(exe, fixtures, work, "good", "fixture_good_c", "good_c_elastic")
    assert r.returncode == 0, r.stderr
    reference = results(good)
    for library, said in (("fixture_fp_env",
                           r"create of model 'fixture_model' changed the floating-point "
                           r"environment \(rounding upward instead of to nearest\)"),
                          ("fixture_ftz_at_load",
                           r"loading the library .* changed the floating-point environment "
                           r"\(flush-to-zero on; denormals-are-zero on\)")):
        r, out = run(exe, fixtures, work, library, library, "fixture_model")
        assert r.returncode == 0, r.stderr
        assert re.search("warning: plugin fixture_model_library: " + said, r.stderr), r.stderr
        got = results(out)
        for f in reference:
            assert got[f] == reference[f], f"{library}: {f} differs from the well-behaved plugin's"


def exits(exe, fixtures, work):
    r, out = run(exe, fixtures, work, "exits", "fixture_exits", "exits")
    assert r.returncode != 0, f"talus run exited 0 after a plugin's exit()\n{r.stderr}"
    assert re.search(r"talus: fatal: the material plugin called exit\(0\) inside model 'exits' "
                     r"from [^ ]*fixture_exits\.so, updating material 'elastic', group '(lower|"
                     r"upper)', particles [0-9.]+, in step [0-9]+", r.stderr), r.stderr
    assert re.search(r"the state .* is in [^ ]*failure_step[0-9]+\.vtu", r.stderr), r.stderr
    assert glob.glob(os.path.join(out, "failure_step*.vtu")), os.listdir(out)
    assert "bug in Talus" not in r.stderr, r.stderr

    case = os.path.join(work, "exits_point.yaml")
    with open(case, "w") as f:
        f.write(POINT.format(library="fixture_exits", model="exits"))
    r = talus(exe, fixtures, ["point", case, "--output", os.path.join(work, "exits_point.csv")])
    assert r.returncode != 0, f"talus point exited 0 after a plugin's exit()\n{r.stderr}"
    assert re.search(r"talus: fatal: the material plugin called exit\(0\) inside model 'exits'",
                     r.stderr), r.stderr


def crash_after(exe, fixtures, work):
    # At rest and long (seconds): the plugin's thread crashes mid-run, 50 ms in.
    scenario = os.path.join(work, "after.yaml")
    with open(scenario, "w") as f:
        f.write(SCENARIO.format(library="fixture_crashes_after_return",
                                model="crashes_after_return")
                .replace("end: 0.2", "end: 100").replace("velocity: [0.5, 0.5]", "velocity: [0, 0]")
                .replace("velocity: [-0.5, -0.5]", "velocity: [0, 0]"))
    r = talus(exe, fixtures, ["run", scenario, "--output-dir", os.path.join(work, "after"),
                              "--allow-large"])
    assert r.returncode == 128 + 11, f"exit {r.returncode}"
    assert re.search(r"outside any plugin call\. This may be a bug in Talus .*or the doing of a "
                     r"plugin that wrote past its arrays .* model 'crashes_after_return' from "
                     r"[^ ]*fixture_crashes_after_return\.so; `talus plugin check` on it", r.stderr,
                     re.S), r.stderr


def one_particle(exe, fixtures, work):
    for model, ends in (("crashes_on_one", r"ends in the same way: signal 11 \(SIGSEGV"),
                        ("exits_on_one", r"ends the process \(exit status 3\)")):
        for threads in ("1", "2"):
            scenario = os.path.join(work, f"{model}.yaml")
            with open(scenario, "w") as f:
                f.write(SCENARIO.format(library="fixture_" + model, model=model))
            r = subprocess.run([exe, "--plugin-path", fixtures, "run", scenario, "--threads",
                                threads, "--output-dir", os.path.join(work, model + threads)],
                               capture_output=True, text=True)
            print(f"$ talus run {model}.yaml ({threads} thread(s))\n  exit {r.returncode}\n"
                  f"  {r.stderr.strip()[-900:]}")
            assert r.returncode != 0, r.stderr
            assert re.search(r"talus: run alone, particle 10 \(group 'lower'\) " + ends +
                             r".*; point [0-9]+ of the batch's [0-9]+.*: its input is what the "
                             r"plugin fails on", r.stderr), r.stderr
            assert glob.glob(os.path.join(work, model + threads, "failure_step*.vtu")), \
                "no state written"


def hangs(exe, fixtures, work):
    scenario = os.path.join(work, "hangs.yaml")
    with open(scenario, "w") as f:
        f.write(SCENARIO.format(library="fixture_hangs", model="hangs"))
    err = os.path.join(work, "hangs.log")
    with open(err, "w") as log:
        p = subprocess.Popen([exe, "--plugin-path", fixtures, "run", scenario, "--threads", "2",
                              "--output-dir", os.path.join(work, "hangs")], stderr=log)
    try:
        said = signalled(p, err)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    print(said)


def signalled(p, err):
    # The call hangs from 1 ms on, the second step; the first output row is
    # written before the first step.
    time.sleep(1.0)
    assert p.poll() is None, open(err).read()
    p.send_signal(signal.SIGINT)
    time.sleep(0.5)
    said = open(err).read()
    assert "talus: SIGINT: the run stops when this step ends, after writing a checkpoint; a " \
           "second signal stops it at once" in said, said
    assert "has not ended" not in said, said
    time.sleep(11.0)  # the second word comes 10 s after the signal
    said = open(err).read()
    assert p.poll() is None, said
    assert re.search(r"talus: the step has not ended 10 s after SIGINT\n(talus: a thread has "
                     r"been inside one call of model 'hangs' from [^ ]*fixture_hangs\.so "
                     r"\(material 'elastic'\) since then\n)+talus: a plugin call that does not "
                     r"return cannot be stopped", said), said
    p.send_signal(signal.SIGINT)
    assert p.wait(timeout=30) == -signal.SIGINT, "a second SIGINT did not end the run"
    return said


def main():
    case, exe, fixtures, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    {"fp_environment": fp_environment, "exit": exits, "crash_after": crash_after,
     "one_particle": one_particle, "hangs": hangs}[case](exe, fixtures, work)
    print("ok")


if __name__ == "__main__":
    main()
