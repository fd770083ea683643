"""The benchmarks in bench/ run as the docs show them: `python bench/X.py`.

Run that way, Python puts bench/ first on the import path, so a script named
like an importable module (one of our packages, a library, the standard
library, a test-suite module a benchmark puts on the path) would be imported
in its place by every `import` of that name, ours or a library's. These tests
check that no script has such a name, that every script's imports resolve
with bench/ first on the path (without running its main), that every
`bench/X.py` the docs, the Makefile and the code name exists, that the docs
(docs/ and docs/studies/) name every script, and that none is shown run with Python's -P flag.
"""

import importlib.util
import json
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
SCRIPTS = sorted(BENCH.glob("*.py"))
PACKAGES = ("campaign", "analysis", "solver", "common", "cortex", "outputs", "studies")


def test_there_are_scripts_and_packages_to_check():
    assert len(SCRIPTS) > 10
    for package in PACKAGES:
        assert (ROOT / package / "__init__.py").is_file(), package


def test_no_script_is_named_like_an_importable_module():
    sys.path.insert(0, str(ROOT / "tests"))      # where the no-op benchmarks find `faults`
    try:
        hidden = {path.name: importlib.util.find_spec(path.stem) for path in SCRIPTS}
    finally:
        sys.path.remove(str(ROOT / "tests"))
    hidden = {name: spec.origin for name, spec in hidden.items() if spec is not None}
    hidden.update({path.name: "the standard library" for path in SCRIPTS if path.stem in sys.stdlib_module_names})
    assert hidden == {}, f"rename these bench scripts, each hides a module: {hidden}"


IMPORT_ALL = """
import importlib, json, pathlib, sys
bench = pathlib.Path(sys.argv[1])
sys.path[0] = str(bench)                    # as `python bench/X.py` sets it
path_then = list(sys.path)
failed = {}
for path in sorted(bench.glob("*.py")):
    sys.path[:] = path_then                 # each script as if run alone (some put tests/ on the path)
    try:
        importlib.import_module(path.stem)  # its imports and definitions; main() runs only as __main__
    except BaseException as err:
        failed[path.name] = f"{type(err).__name__}: {err}"
packages = {name: getattr(sys.modules.get(name), "__file__", None) for name in sys.argv[2:]}
print(json.dumps({"failed": failed, "packages": packages}))
"""


def test_every_script_imports_with_bench_first_on_the_path(tmp_path):
    out = subprocess.run([sys.executable, "-c", IMPORT_ALL, str(BENCH), *PACKAGES], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["failed"] == {}
    for name, origin in result["packages"].items():   # the ones the scripts imported came from the project
        assert origin is None or pathlib.Path(origin).resolve() == ROOT / name / "__init__.py", (name, origin)
    assert any(origin is not None for origin in result["packages"].values())


def test_every_named_script_exists_and_runs_plainly():
    texts = {path: path.read_text() for path in
             [ROOT / "README.md", ROOT / "Makefile", *(ROOT / "docs").rglob("*.md"),
              *SCRIPTS, *(ROOT / "tests").glob("*.py"), *(ROOT / "solver").rglob("*.py"),
              *(ROOT / "analysis").rglob("*.py"), *(ROOT / "campaign").rglob("*.py"),
              *(ROOT / "studies").rglob("*.py")]}
    named = {(path.name, m) for path, text in texts.items() for m in re.findall(r"bench/([a-z0-9_]+)\.py", text)}
    missing = sorted({(where, name) for where, name in named if not (BENCH / f"{name}.py").is_file()})
    assert missing == []
    in_docs = {name for where, name in named if where.endswith(".md")}
    assert sorted(path.stem for path in SCRIPTS if path.stem not in in_docs) == [], "bench scripts no doc names"
    run_with_p = sorted(path.name for path, text in texts.items() if re.search(r"python3? -P\b", text))
    assert run_with_p == []
