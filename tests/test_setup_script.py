""".ci/packages (the Debian step of .ci/setup) against stub dpkg-query, apt-cache and apt-get.

The stubs read a fixture (what is installed, what the archive has) from a JSON
file, log every call with its arguments, and model Mesa's lockstep versions: a
package installed at version V moves its installed siblings of the same source
package to V.  PATH holds the stubs and links to the few basic tools the script
uses, nothing else, so the real dpkg and apt are never reached.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ROOT / ".ci" / "packages"
SETUP = ROOT / ".ci" / "setup"

OLD, NEW = "22.3.6-1+deb12u1", "22.3.6-1+deb12u2"
MESA = ["libegl-mesa0", "libgbm1", "libgl1-mesa-dri", "libglapi-mesa", "libglx-mesa0"]
REQUIRED = ["libegl1", "libegl-mesa0", "libgl1", "libgl1-mesa-dri", "libgbm1", "libusb-1.0-0"]
# what the script may call besides the stubs (bash builtins do the parsing)
TOOLS = ["bash", "env", "dirname", "tail", "cat", "sed", "awk", "grep", "tr", "head"]

pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")

STUB = r'''#!{python} -IS
# stub of dpkg-query / apt-cache / apt-get / id / sudo: see tests/test_setup_script.py
import json, os, signal, sys
signal.signal(signal.SIGPIPE, signal.SIG_DFL)   # die of SIGPIPE as the real tools do
cmd, args = os.path.basename(sys.argv[0]), sys.argv[1:]
fixture = os.environ["STUB_FIXTURE"]
with open(fixture) as f:
    fx = json.load(f)
with open(os.environ["STUB_LOG"], "a") as f:
    f.write(" ".join([cmd] + args) + "\n")
inst = fx["installed"]          # name -> [version, source]
arch = fx["archive"]            # name -> {"source": ..., "versions": [newest first]}

def source(p):
    return arch[p]["source"] if p in arch else (inst[p][1] if p in inst else p)

if cmd == "id":
    print(fx.get("uid", 0))
elif cmd == "sudo":
    os.execvp(args[0], args)
elif cmd == "dpkg-query":
    fmt = next(a[3:] for a in args if a.startswith("-f="))
    fmt = fmt.replace("\\n", "\n").replace("\\t", "\t")
    rows = [(p, v, s, "install ok installed") for p, (v, s) in sorted(inst.items())]
    rows.insert(0, ("libfoo-old", "1.0", "foo", "deinstall ok config-files"))
    # a real machine lists a thousand packages or more, with long names: more
    # than a pipe holds (64 KiB) in any of the fields, so that a reader that stops
    # early always SIGPIPEs this writer, as it did the real dpkg-query
    rows += [("zz-filler-%05d-named-as-long-as-many-real-packages" % i, "1:2.34.5+dfsg-%d+deb12u1" % i,
              "zz-filler-source-%05d-with-a-long-name" % i, "install ok installed")
             for i in range(fx.get("filler", 0))]
    names = [a for a in args if not a.startswith("-")]   # none: every package
    rows = [r for r in rows if not names or r[0] in names]
    for p, v, s, st in rows:
        sys.stdout.write(fmt.replace("${Package}", p).replace("${Version}", v)
                         .replace("${source:Package}", s).replace("${Status}", st))
    sys.stdout.flush()
    unknown = [n for n in names if n not in [r[0] for r in rows]]
    for n in unknown:
        sys.stderr.write("dpkg-query: no packages found matching %s\n" % n)
    sys.exit(1 if unknown else 0)
elif cmd == "apt-cache":
    p = args[-1]
    if p not in arch:
        sys.exit("E: No packages found" if args[0] == "show" else 0)
    a = arch[p]
    if args[0] == "show":
        print("Package: %s" % p)
        if a["source"] != p:
            # Debian adds the source's version where it differs from the package's
            print("Source: %s%s" % (a["source"], " (%s)" % a["source_version"] if "source_version" in a else ""))
        print("Version: %s\nArchitecture: amd64\n" % a["versions"][0])
    elif args[0] == "madison":
        for v in a["versions"]:
            print("%10s | %s | http://deb.debian.org/debian bookworm/main amd64 Packages" % (p, v))
elif cmd == "apt-get":
    words = [a for a in args if not a.startswith("-")]
    sim = "-s" in args or "--simulate" in args
    if words[0] == "update":
        if fx.get("fail_update"):
            sys.exit("E: Failed to fetch http://deb.debian.org/debian/dists/bookworm/InRelease")
        sys.exit(0)
    assert words[0] == "install", args
    lines, new = [], dict(inst)
    for w in words[1:]:
        p, _, v = w.partition("=")
        if p not in arch:
            sys.exit("E: Unable to locate package %s" % p)
        v = v or arch[p]["versions"][0]
        if v not in arch[p]["versions"]:
            sys.exit("E: Version '%s' for '%s' was not found" % (v, p))
        # the packages built from one source depend on each other at exactly one version
        for q in sorted(set([p] + [q for q, (_, s) in inst.items() if s == source(p)])):
            if q in new and new[q][0] == v:
                continue
            old = " [%s]" % inst[q][0] if q in inst else ""
            lines.append("Inst %s%s (%s Debian:12.12/stable [amd64])" % (q, old, v))
            new[q] = [v, source(p)]
    if sim:
        print("NOTE: This is only a simulation!")
        print("\n".join(lines + [l.replace("Inst", "Conf", 1) for l in lines]))
        sys.exit(0)
    if fx.get("fail_install"):
        print("Get:1 http://deb.debian.org/debian bookworm/main amd64 %s" % words[1])
        sys.exit("E: Failed to fetch http://deb.debian.org/debian/pool/main/%s.deb  404  Not Found" % words[1])
    fx["installed"] = new
    with open(fixture, "w") as f:
        json.dump(fx, f)
'''


def installed(mesa=OLD, missing=()):
    """A machine with Mesa at `mesa`, libglvnd's libegl1 / libgl1, and libusb, less `missing`."""
    inst = {p: [mesa, "mesa"] for p in MESA}
    inst.update({"libegl1": ["1.6.0-1", "libglvnd"], "libgl1": ["1.6.0-1", "libglvnd"],
                 "libusb-1.0-0": ["2:1.0.26-1", "libusb-1.0"], "libosmesa6": [mesa, "mesa"]})
    return {p: v for p, v in inst.items() if p not in missing}


def archive(mesa_versions):
    arch = {p: {"source": "mesa", "versions": list(mesa_versions), "source_version": "22.3.6-1"}
            for p in MESA + ["libosmesa6"]}
    arch.update({p: {"source": "libglvnd", "versions": ["1.6.0-1"]} for p in ("libegl1", "libgl1")})
    arch["libusb-1.0-0"] = {"source": "libusb-1.0", "versions": ["2:1.0.26-1"]}
    return arch


class Machine:
    def __init__(self, tmp_path: Path, fixture: dict, debian: bool = True):
        self.tmp = tmp_path
        self.fixture_path = tmp_path / "fixture.json"
        self.fixture_path.write_text(json.dumps(fixture))
        self.calls_path = tmp_path / "calls.log"
        self.calls_path.write_text("")
        self.log = tmp_path / "setup.log"
        stubs = tmp_path / "stubs"
        tools = tmp_path / "tools"
        stubs.mkdir()
        tools.mkdir()
        # the base interpreter, isolated and without site: a stub starts in ~20 ms
        python = os.path.realpath(getattr(sys, "_base_executable", sys.executable))
        text = STUB.replace("{python}", python)
        for cmd in ["apt-cache", "apt-get", "id", "sudo"] + (["dpkg-query"] if debian else []):
            (stubs / cmd).write_text(text)
            (stubs / cmd).chmod(0o755)
        for t in TOOLS:
            real = shutil.which(t)
            if real:
                (tools / t).symlink_to(real)
        self.env = {"PATH": f"{stubs}:{tools}", "STUB_FIXTURE": str(self.fixture_path),
                    "STUB_LOG": str(self.calls_path), "GLVOX_SETUP_LOG": str(self.log),
                    "HOME": str(tmp_path), "LANG": "C"}

    def run(self, script: Path = PACKAGES) -> subprocess.CompletedProcess:
        return subprocess.run([str(self.tmp / "tools" / "bash"), str(script)], env=self.env,
                              capture_output=True, text=True, timeout=60)

    def calls(self, cmd: str = "apt-get") -> list[str]:
        return [c for c in self.calls_path.read_text().splitlines() if c.split()[0] == cmd]

    def installs(self) -> list[list[str]]:
        """The packages of each real (not simulated) apt-get install, in order."""
        return [[w for w in c.split()[1:] if not w.startswith("-")][1:]
                for c in self.calls() if " install " in c and " -s " not in c]

    def state(self) -> dict:
        return json.loads(self.fixture_path.read_text())["installed"]


def lines(out: str) -> list[str]:
    return [l for l in out.splitlines() if l.strip()]


def test_all_installed_calls_no_apt_get(tmp_path):
    m = Machine(tmp_path, {"installed": installed(), "archive": archive([NEW]), "filler": 3000})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert m.calls() == [] and m.calls("apt-cache") == []
    assert lines(r.stdout) == ["setup: Debian packages: all there"] and r.stderr == ""


def test_missing_with_siblings_installed_is_pinned_to_their_version(tmp_path):
    # the machine: libosmesa6 and libusb-1.0-0 missing, Mesa at deb12u1, a
    # thousand more packages listed after Mesa's (the old `| awk '...; exit'` died of SIGPIPE)
    m = Machine(tmp_path, {"installed": installed(missing=["libosmesa6", "libusb-1.0-0"]),
                           "archive": archive([NEW, OLD]), "filler": 3000})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stderr == ""
    assert m.installs() == [["libusb-1.0-0"], [f"libosmesa6={OLD}"]]
    assert m.calls("sudo") == []   # root: no sudo
    assert lines(r.stdout) == ["setup: installing missing Debian packages: libusb-1.0-0",
                               f"setup: installing the OSMesa fallback: libosmesa6={OLD}"]
    # nothing that was installed moved
    assert {p: v for p, v in m.state().items() if p in MESA} == {p: [OLD, "mesa"] for p in MESA}


def test_required_missing_archive_only_newer_is_installed_with_the_upgrade_named(tmp_path):
    m = Machine(tmp_path, {"installed": installed(missing=["libgl1-mesa-dri", "libosmesa6"]),
                           "archive": archive([NEW]), "filler": 3000})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    out = lines(r.stdout)
    assert out[0] == "setup: installing missing Debian packages: libgl1-mesa-dri"
    assert out[1] == ("setup: note: this also upgrades installed libegl-mesa0 libgbm1 libglapi-mesa "
                      f"libglx-mesa0: the archive no longer has mesa {OLD}, and the libraries built "
                      "from one source must have one version (Mesa's must match)")
    # Mesa moved to deb12u2 for the required one: OSMesa at that version now upgrades nothing
    assert out[2:] == [f"setup: installing the OSMesa fallback: libosmesa6={NEW}"]
    assert m.installs() == [["libgl1-mesa-dri"], [f"libosmesa6={NEW}"]]


def test_optional_osmesa_that_would_upgrade_mesa_is_skipped_with_how_to(tmp_path):
    # this machine: EGL's packages all there at deb12u1, the archive has only deb12u2
    m = Machine(tmp_path, {"installed": installed(missing=["libosmesa6"]),
                           "archive": archive([NEW]), "filler": 3000})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert lines(r.stdout) == [
        "setup: EGL is used; OSMesa (libosmesa6) was not added: it would upgrade installed packages "
        "libegl-mesa0 libgbm1 libgl1-mesa-dri libglapi-mesa libglx-mesa0 (Mesa's versions must match); "
        "to add it by hand: apt-get install --no-install-recommends libosmesa6"]
    assert m.installs() == []
    assert [c for c in m.calls() if "install" in c] == [
        "apt-get install -s --no-install-recommends libosmesa6"]
    assert m.state() == installed(missing=["libosmesa6"])


def test_not_root_uses_sudo_for_changes_only(tmp_path):
    m = Machine(tmp_path, {"installed": installed(missing=["libosmesa6"]), "uid": 1000,
                           "archive": archive([NEW])})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert m.calls("sudo") == ["sudo apt-get update -qq"]
    assert r.stdout.rstrip().endswith("to add it by hand: sudo apt-get install --no-install-recommends libosmesa6")


def test_not_debian_says_what_to_install_and_succeeds(tmp_path):
    m = Machine(tmp_path, {"installed": {}, "archive": archive([NEW])}, debian=False)
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    out = lines(r.stdout)
    assert len(out) == 1 and out[0].startswith("setup: not a Debian system: install")
    assert "libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgbm1" in out[0]
    assert m.calls() == [] and m.calls("apt-cache") == []


def test_failed_install_names_the_step_and_shows_the_log(tmp_path):
    m = Machine(tmp_path, {"installed": installed(missing=["libusb-1.0-0"]),
                           "archive": archive([OLD]), "fail_install": True, "filler": 3000})
    r = m.run()
    assert r.returncode == 1, r.stdout + r.stderr
    assert lines(r.stdout) == ["setup: installing missing Debian packages: libusb-1.0-0"]
    err = r.stderr
    assert "setup: FAILED (exit 1) at step: Debian packages: apt-get install libusb-1.0-0" in err
    assert f"the end of {m.log}" in err
    assert "libusb-1.0-0.deb  404  Not Found" in err.splitlines()[-1]


def test_failed_update_with_only_osmesa_missing_goes_on(tmp_path):
    m = Machine(tmp_path, {"installed": installed(missing=["libosmesa6"]),
                           "archive": archive([OLD]), "fail_update": True})
    r = m.run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert lines(r.stdout) == [f"setup: EGL is used; OSMesa (libosmesa6) was not added: apt-get update "
                               f"failed (see {m.log})"]
    assert m.installs() == []


def test_setup_reports_a_failed_step_once(tmp_path):
    # .ci/setup itself: the package step fails inside .ci/packages, which reports;
    # setup stops with its status and does not report it a second time
    m = Machine(tmp_path, {"installed": installed(missing=["libusb-1.0-0"]),
                           "archive": archive([OLD]), "fail_install": True})
    r = m.run(SETUP)
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stderr.count("setup: FAILED") == 1
    assert "at step: Debian packages: apt-get install libusb-1.0-0" in r.stderr
