"""The progress line of a run in stages follows a stage that ends early
(until: at rest): after the first stage of 100 s came to rest at T, the
lines give the end as T + 0.5 s, not 100.5 s, and an ETA to it.

usage: eta_staged.py TALUS_EXE SCENARIO WORK_DIR"""
import re
import subprocess
import sys


def main():
    exe, scenario, work = sys.argv[1:4]
    r = subprocess.run([exe, "run", scenario, "--output-dir", work, "--force",
                        "--progress-every", "0.0001"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    begin = re.search(r"stage 'after' begins at t = ([0-9.e+-]+) s", r.stderr)
    assert begin, r.stderr
    t = float(begin.group(1))
    assert t < 10.0, f"the first stage did not end early ({t} s)"
    after = r.stderr[begin.end():]
    ends = [float(x) for x in re.findall(r"progress: step [0-9]+  t = [0-9.e+-]+ / ([0-9.e+-]+) s",
                                         after)]
    assert ends, "no progress line in the second stage"
    # printed to 4 significant digits
    assert all(abs(e - (t + 0.5)) <= 1e-3 * (t + 0.5) for e in ends), (t, ends[:5])
    print(f"stage 2 begins at {t:.6g} s; progress ends {sorted(set(ends))}")
    print("ok")


if __name__ == "__main__":
    main()
