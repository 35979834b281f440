"""Out of memory: a scenario larger than the process may allocate (an
address-space limit of 600 MB, as ulimit -v or a job's limit sets, against
about 1.1 GB) is refused with what was being made and how much it needs,
not "internal error: std::bad_alloc".

usage: out_of_memory.py TALUS_EXE SCENARIO"""
import resource
import subprocess
import sys


def main():
    exe, scenario = sys.argv[1:3]
    limit = 600 * 1000 * 1000

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    r = subprocess.run([exe, "validate", scenario], capture_output=True, text=True,
                       preexec_fn=cap, env={"OMP_NUM_THREADS": "1"})
    print(f"exit {r.returncode}\n{r.stderr}")
    assert r.returncode == 1, r.returncode
    assert "out of memory while making the grid and the particles (about 1.1 GB needed" \
        in r.stderr, r.stderr
    assert "internal error" not in r.stderr and "bad_alloc" not in r.stderr, r.stderr
    print("ok")


if __name__ == "__main__":
    main()
