"""Checks a provenance record against independent facts: the JSON parses,
the talus version is what `talus --version` prints, each plugin's sha256 is
the one hashlib computes from the file, the input's sha256 likewise, and
the material's parameters are the values the scenario gives (passed on the
command line as KEY=VALUE).

usage: check_provenance.py PROVENANCE.json TALUS_EXE MATERIAL KEY=VALUE..."""
import hashlib
import json
import subprocess
import sys


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def main():
    record_file, talus, material = sys.argv[1:4]
    expected = dict(kv.split("=", 1) for kv in sys.argv[4:])
    with open(record_file) as f:
        rec = json.load(f)
    version = subprocess.run([talus, "--version"], capture_output=True, text=True,
                             check=True).stdout.split()
    assert rec["talus_version"] in version, (rec["talus_version"], version)
    assert rec["material_abi"] == "1.2", rec["material_abi"]
    assert rec["input"]["sha256"] == sha256(rec["input"]["file"]), rec["input"]
    names = [m["name"] for m in rec["materials"]]
    assert material in names, names
    m = rec["materials"][names.index(material)]
    lib = m["library"]
    assert lib["sha256"] == sha256(lib["path"]), lib
    assert m["model"].startswith(lib["name"] + "/"), m["model"]
    for key, value in expected.items():
        assert m["parameters"][key] == float(value), (key, m["parameters"][key], value)
    print("provenance ok:", m["model"], lib["sha256"][:12])


main()
