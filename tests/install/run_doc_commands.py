"""Runs the shell commands of a documentation page, in order, in a fresh
folder, against an installed Talus: the page's ```sh blocks joined into
one bash script (set -euo pipefail), so a command that fails fails the
test. Blocks fenced as ```sh install (building and installing Talus
itself) are skipped: the test installs the build under test at ~/talus,
HOME being a folder of the test's own.

usage: run_doc_commands.py DOC.md PREFIX WORK"""
import os
import re
import shutil
import subprocess
import sys


def main():
    doc, prefix, work = sys.argv[1:4]
    with open(doc) as f:
        text = f.read()
    blocks = re.findall(r"^```sh( install)?\n(.*?)^```", text, flags=re.S | re.M)
    script = "\n".join(body for skip, body in blocks if not skip)
    if not script.strip():
        sys.exit(f"{doc}: no ```sh blocks")
    shutil.rmtree(work, ignore_errors=True)
    home = os.path.join(work, "home")
    os.makedirs(home)
    # The page's ~/talus is the installation under test.
    os.symlink(os.path.abspath(prefix), os.path.join(home, "talus"))
    env = {k: v for k, v in os.environ.items() if k not in ("TALUS_PLUGIN_PATH", "XDG_DATA_HOME")}
    env["HOME"] = home
    run = os.path.join(work, "run")
    os.makedirs(run)
    with open(os.path.join(work, "commands.sh"), "w") as f:
        f.write("set -euo pipefail\nset -x\n" + script)
    r = subprocess.run(["bash", os.path.join(work, "commands.sh")], cwd=run, env=env)
    if r.returncode != 0:
        sys.exit(f"{doc}: a command failed (exit {r.returncode}); the script is "
                 f"{os.path.join(work, 'commands.sh')}")
    print(f"{doc}: {len(blocks)} blocks of commands ran")


main()
