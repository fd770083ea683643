"""The public API is typed: every name in the `__all__` of the packages that
`[tool.mypy] packages` lists is annotated, and the type checker finds a call
with a wrong unit-suffixed keyword (`make typecheck`, the first step of `make
test`, checks the whole project)."""

import importlib
import inspect
import subprocess
import sys
import tomllib

import pytest

from conftest import ROOT

TYPED = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]["packages"]
PUBLIC = [".".join(init.parent.relative_to(ROOT).parts) for top in TYPED
          for init in sorted((ROOT / top).rglob("__init__.py"))
          if "__all__" in init.read_text()]


def _unannotated(obj):
    """The parameters (and 'return') of a function, or of a class's __init__, that lack an annotation."""
    func = obj.__init__ if inspect.isclass(obj) else obj
    if inspect.isclass(obj) and func is object.__init__:
        return []
    sig = inspect.signature(func)
    missing = [n for n, p in sig.parameters.items() if n not in ("self", "cls")
               and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and p.annotation is p.empty]
    return missing + (["return"] if sig.return_annotation is sig.empty and not inspect.isclass(obj) else [])


@pytest.mark.parametrize("package", PUBLIC)
def test_every_public_function_and_class_is_annotated(package):
    module = importlib.import_module(package)
    bad = {}
    for name in module.__all__:
        obj = getattr(module, name)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            missing = _unannotated(obj)
            if missing:
                bad[name] = missing
    assert bad == {}, f"{package}: public names without annotations: {bad}"


def test_the_type_checker_catches_a_wrong_unit_keyword(tmp_path):
    """(`make test` runs the type checker over the whole project first, `make typecheck`, and
    stops if it finds anything: this is not run again here.)"""
    wrong = tmp_path / "wrong_unit.py"
    wrong.write_text("from solver.model import Shell\n"
                     "Shell(volume_um=4300.0, h0_um=12.0, dh_um=0.5, bulk_mN_per_m=25.0,\n"
                     "      shear_mN_per_m=8.33, tension_mN_per_m=1.5)\n")
    run = subprocess.run([sys.executable, "-m", "mypy", "--no-incremental", "--follow-imports=silent",
                          "--ignore-missing-imports", str(wrong)], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 1, run.stdout + run.stderr
    assert 'Unexpected keyword argument "volume_um"' in run.stdout
