#!/usr/bin/env python3
"""Every shared library the installed binaries need is provided by deploy/Containerfile's
runtime stage (issue 32, item 9: the runtime stage once lacked libspqr2 and the container did
not start).

    python3 tests/deploy/container_libs_test.py deploy/Containerfile BINARY...

For each binary, `ldd` names the libraries it loads; `dpkg -S` the Debian package that ships
each one, on this machine (where the build's own -dev packages pulled them in). The runtime
stage provides a package when it installs it, when an installed package depends on it (what
apt installs with it, read from dpkg's own records: no network), or when it is in every Debian
image (Essential, or Priority required: debian:12-slim has those). A library outside all three
fails the test, named with its package and the line to add.
"""
import os
import re
import subprocess
import sys


def runtime_packages(containerfile):
    """The packages the last stage's apt-get install lines name."""
    text = open(containerfile).read().replace("\\\n", " ")
    stages = re.split(r"^FROM\s", text, flags=re.M)
    last = stages[-1]
    packages = []
    for command in re.findall(r"apt-get install([^&\n]*)", last):
        packages += [w for w in command.split() if not w.startswith("-")]
    return packages


def dpkg_records():
    """Per installed package: its dependencies (names only) and whether every image has it."""
    out = subprocess.run(["dpkg-query", "-W", "-f",
                          "${Package}\t${Essential}\t${Priority}\t${Pre-Depends}, ${Depends}\n"],
                         capture_output=True, text=True, check=True).stdout
    records = {}
    for line in out.splitlines():
        name, essential, priority, depends = line.split("\t")
        names = set()
        for clause in depends.split(","):
            # "a (>= 1) | b": any alternative will do; take every installed one.
            for alternative in clause.split("|"):
                word = alternative.strip().split(" ")[0].split(":")[0]
                if word:
                    names.add(word)
        records[name] = (essential == "yes" or priority == "required", names)
    return records


def closure(roots, records):
    seen, todo = set(), list(roots)
    while todo:
        p = todo.pop()
        if p in seen or p not in records:
            continue
        seen.add(p)
        todo.extend(records[p][1])
    return seen


def libraries(binary):
    out = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True).stdout
    libs = []
    for line in out.splitlines():
        m = re.search(r"=>\s+(/\S+)", line)
        if m:
            libs.append(m.group(1))
        elif "not found" in line:
            raise SystemExit("FAIL: %s: %s" % (binary, line.strip()))
    return libs


def package_of(path):
    """The package that ships the library, through Debian's alternatives (libblas.so.3 is a
    link in /etc/alternatives to one BLAS's file)."""
    r = subprocess.run(["dpkg", "-S", path], capture_output=True, text=True)
    if r.returncode != 0:
        path = os.path.realpath(path)
        r = subprocess.run(["dpkg", "-S", path], capture_output=True, text=True)
    if r.returncode != 0:
        # /lib is a link to /usr/lib on Debian 12: dpkg knows one spelling.
        other = path.replace("/usr/lib/", "/lib/", 1) if path.startswith("/usr/lib/") else \
            path.replace("/lib/", "/usr/lib/", 1)
        r = subprocess.run(["dpkg", "-S", other], capture_output=True, text=True)
    if r.returncode != 0:
        return None
    return r.stdout.split(":")[0].strip()


def main():
    containerfile, binaries = sys.argv[1], sys.argv[2:]
    listed = runtime_packages(containerfile)
    records = dpkg_records()
    missing_records = [p for p in listed if p not in records]
    if missing_records:
        raise SystemExit("FAIL: %s installs %s, not installed here (cannot read their "
                         "dependencies)" % (containerfile, ", ".join(missing_records)))
    base = {p for p, (everywhere, _) in records.items() if everywhere}
    provided = closure(listed, records) | closure(base, records)
    failures = []
    checked = 0
    for binary in binaries:
        for lib in sorted(set(libraries(binary))):
            package = package_of(lib)
            checked += 1
            if package is None:
                failures.append("%s: %s belongs to no Debian package" % (binary, lib))
            elif package not in provided:
                failures.append("%s needs %s, from package %s, which the runtime stage of %s "
                                "does not install: add %s to its apt-get install line"
                                % (binary, lib, package, containerfile, package))
    for f in failures:
        print("FAIL: " + f)
    print("container libraries: %d checked, %d missing" % (checked, len(failures)))
    print("%d passed, %d failed" % (1 if not failures else 0, 1 if failures else 0))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
