"""The `.pyi` stubs: every public function / class of the compiled extension has an entry in
`_laparo.pyi` and vice versa; every submodule's stub is the one `scripts/gen_stubs.py` generates
from its source (so it lists exactly the module's public functions and classes)."""
import ast
import importlib
import inspect
import subprocess
import sys
from pathlib import Path

import pytest

import laparo
from laparo import _laparo

PKG = Path(laparo.__file__).resolve().parent
SRC_PKG = Path(__file__).resolve().parents[1] / "python" / "laparo"
SUBMODULES = ["depth", "cats", "stereo", "cpc", "mpm", "shard", "features", "register", "fem"]


def stub_names(path):
    tree = ast.parse(path.read_text())
    return {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}


def test_extension_and_its_stub_list_the_same_names():
    ext = {n for n, v in vars(_laparo).items() if not n.startswith("_") and (callable(v) or inspect.isclass(v))}
    stub = stub_names(PKG / "_laparo.pyi")
    assert ext - stub == set(), f"functions of the extension without a stub: {sorted(ext - stub)}"
    assert stub - ext == set(), f"stubs without a function in the extension: {sorted(stub - ext)}"


def test_stub_signatures_of_the_extension_match():
    """Parameter names (in order) of each stubbed function equal the extension's."""
    tree = ast.parse((PKG / "_laparo.pyi").read_text())
    for n in tree.body:
        if isinstance(n, ast.FunctionDef):
            f = getattr(_laparo, n.name)
            want = [a.arg for a in n.args.args]
            got = list(inspect.signature(f).parameters)
            assert got == want, (n.name, got, want)


@pytest.mark.parametrize("name", SUBMODULES)
def test_submodule_stub_lists_its_public_api(name):
    mod = importlib.import_module(f"laparo.{name}")
    public = {
        n for n, v in vars(mod).items()
        if not n.startswith("_") and (inspect.isfunction(v) or inspect.isclass(v)) and getattr(v, "__module__", "") == mod.__name__
    }
    stub = {n for n in stub_names(PKG / f"{name}.pyi") if not n.startswith("_")}
    assert public == stub, (name, sorted(public ^ stub))
    assert (PKG / "py.typed").exists()


def test_stubs_are_up_to_date():
    script = SRC_PKG.parents[1] / "scripts" / "gen_stubs.py"
    r = subprocess.run([sys.executable, str(script), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
