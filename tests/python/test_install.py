"""`cmake --install build --component python --prefix P` puts the module and its type stubs where the
interpreter finds them under P; imported with only that folder on the path, every public function
and class has a docstring, and the stubs (slamvdb.pyi) match the module: the same public names,
and mypy's stubtest finds no difference.

Run by CTest (Python.Install) with SLAMVDB_BUILD_DIR and CMAKE_COMMAND set.
"""
import ast
import json
import os
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

BUILD = os.environ.get("SLAMVDB_BUILD_DIR", "build")
CMAKE = os.environ.get("CMAKE_COMMAND", "cmake")

# Run with only the installed folder on the path: public names and what lacks a docstring.
INSPECT = r"""
import inspect, json, slamvdb
def documented(obj):
    doc = (getattr(obj, "__doc__", None) or "").strip()
    # pybind11 starts a function's docstring with its signature; the text must say more than that.
    if callable(obj) and not inspect.isclass(obj):
        doc = "\n".join(l for l in doc.split("\n") if not l.startswith(getattr(obj, "__name__", "?") + "("))
    return bool(doc.strip())
public, undocumented = {}, []
for name in dir(slamvdb):
    if name.startswith("_"):
        continue
    obj = getattr(slamvdb, name)
    members = sorted(m for m in vars(obj) if not m.startswith("_")) if inspect.isclass(obj) else []
    public[name] = members
    if not documented(obj):
        undocumented.append(name)
    for m in members + (["__init__"] if inspect.isclass(obj) and "__init__" in vars(obj) else []):
        if not documented(vars(obj)[m]):
            undocumented.append(name + "." + m)
print(json.dumps({"file": slamvdb.__file__, "public": public, "undocumented": undocumented}))
"""


def stub_names(path):
    """Public top-level names of the stub, with their classes' public members."""
    names = {}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)) and not node.name.startswith("_"):
            members = [n.name for n in getattr(node, "body", []) if isinstance(n, ast.FunctionDef)] \
                if isinstance(node, ast.ClassDef) else []
            names[node.name] = sorted(m for m in members if not m.startswith("_"))
    return names


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    prefix = tmp_path_factory.mktemp("prefix")
    subprocess.run([CMAKE, "--install", BUILD, "--component", "python", "--prefix", str(prefix)], check=True,
                   stdout=subprocess.DEVNULL)
    modules, stubs = list(prefix.rglob("slamvdb*.so")), list(prefix.rglob("slamvdb.pyi"))
    assert len(modules) == 1 and len(stubs) == 1, (modules, stubs)
    site = modules[0].parent
    assert stubs[0].parent == site
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["PYTHONPATH"] = str(site)
    return prefix, site, env


def test_installed_where_the_interpreter_looks(installed):
    prefix, site, env = installed
    # Debian's python3 searches PREFIX/lib/python3.X/dist-packages for PREFIX = /usr/local (the
    # default prefix); other interpreters lib/python3.X/site-packages.
    folder = "dist-packages" if "deb_system" in sysconfig.get_scheme_names() else "site-packages"
    assert site.relative_to(prefix) == Path("lib") / f"python{sys.version_info[0]}.{sys.version_info[1]}" / folder
    if folder == "dist-packages":
        assert f"/usr/local/lib/python{sys.version_info[0]}.{sys.version_info[1]}/dist-packages" in sys.path


def test_imports_from_the_prefix_alone_with_docstrings_and_matching_stubs(installed, tmp_path):
    prefix, site, env = installed
    r = subprocess.run([sys.executable, "-s", "-c", INSPECT], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    found = json.loads(r.stdout)
    assert Path(found["file"]).parent == site  # not a build tree
    assert found["undocumented"] == []
    stubs = stub_names(site / "slamvdb.pyi")
    if "TextEncoder" not in found["public"]:  # a build without libtorch
        stubs.pop("TextEncoder")
    assert stubs == found["public"]


def test_stubtest_finds_no_difference(installed, tmp_path):
    prefix, site, env = installed
    pytest.importorskip("mypy.stubtest", reason="mypy (Debian's python3-mypy) is not installed")
    allow = tmp_path / "allowlist.txt"
    allow.write_text(
        "slamvdb.TextEncoder\n"  # absent without libtorch; --ignore-unused-allowlist otherwise
        # pybind11's own machinery, which a stub cannot (and editors need not) name: its metaclass
        # (the classes' members are still checked), and the "No constructor defined" __init__ that
        # pybind11 gives a class constructed only by QuerySet.load.
        "slamvdb.Map\nslamvdb.QuerySet\nslamvdb.QuerySet.__init__\n")
    env = dict(env, MYPYPATH=str(site))
    r = subprocess.run([sys.executable, "-m", "mypy.stubtest", "slamvdb", "--allowlist", str(allow),
                        "--ignore-unused-allowlist"], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
