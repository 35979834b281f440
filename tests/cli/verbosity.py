"""`talus --quiet` and `--verbose` (README, "Set-up"): quiet says nothing
but errors and warnings, and writes the same files; verbose names each
plugin loaded with its file's SHA-256, each output written (one line per
row of diagnostics.csv) and every message of a plugin.

usage: verbosity.py TALUS_EXE SCENARIO_DIR FIXTURE_DIR WORK_DIR"""
import hashlib
import os
import re
import shutil
import subprocess
import sys


def talus(exe, args):
    r = subprocess.run([exe] + args, capture_output=True, text=True,
                       env=dict(os.environ, OMP_NUM_THREADS="1"))
    print(f"$ talus {' '.join(args)}\n  exit {r.returncode}\n  {r.stderr.strip()[-600:]}")
    assert r.returncode == 0, r.stderr
    return r


def rows(folder):
    with open(os.path.join(folder, "diagnostics.csv")) as f:
        return sum(1 for _ in f) - 1


def main():
    exe, scenarios, fixtures, work = sys.argv[1:5]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    small = os.path.join(scenarios, "small_run.yaml")

    # Quiet: nothing said, the files all there; the option may follow the
    # command's own (as --plugin-path may).
    r = talus(exe, ["run", small, "--output-dir", os.path.join(work, "q"), "--quiet"])
    assert r.stderr == "" and r.stdout == "", (r.stdout, r.stderr)
    assert rows(os.path.join(work, "q")) == 5
    r = talus(exe, ["-q", "validate", small])
    assert r.stderr == "" and r.stdout == "", (r.stdout, r.stderr)

    # Verbose: the plugin and its digest, every output.
    out = os.path.join(work, "v")
    r = talus(exe, ["--verbose", "run", small, "--output-dir", out])
    m = re.search(r"talus: material 'elastic': model 'talus_linear_elastic/linear_elastic' \S+ "
                  r"from (\S+) \(library \S+, SHA-256 ([0-9a-f]{64})\)", r.stderr)
    assert m, r.stderr
    with open(m.group(1), "rb") as f:
        assert hashlib.sha256(f.read()).hexdigest() == m.group(2), "not the file's SHA-256"
    said = [int(k) for k in re.findall(r"talus: output (\d+) at t = ", r.stderr)]
    assert said == list(range(rows(out))) and len(said) == 5, said
    assert re.search(r"talus: \d+ steps to t = 0.2 s", r.stderr), r.stderr

    # Every message of a plugin (256, one per particle) under --verbose; 20
    # and the count of the rest otherwise, and under --quiet (they are
    # warnings).
    logs = os.path.join(scenarios, "plugin_logs.yaml")
    for flag, shown, count in (("--verbose", 256, None), ("--quiet", 20, 236), (None, 20, 236)):
        args = ["--plugin-path", fixtures, "run", logs, "--output-dir",
                os.path.join(work, "logs"), "--force"] + ([flag] if flag else [])
        r = talus(exe, args)
        got = len(re.findall(r"^warning: plugin abi11_fixture ", r.stderr, re.M))
        assert got == shown, f"{flag}: {got} messages shown, not {shown}"
        note = re.search(r"sent (\d+) message\(s\) more than the 20 shown", r.stderr)
        assert (int(note.group(1)) if note else None) == count, (flag, r.stderr[-300:])
        if flag == "--quiet":
            assert not re.search(r"^talus: (?!note: plugin)", r.stderr, re.M), r.stderr
    print("ok")


if __name__ == "__main__":
    main()
