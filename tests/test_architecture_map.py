"""The README's folder map and docs/architecture.md's module map match the tree:
every folder the README names exists and every top-level folder of the
project is named; every module of the packages (and of `studies/`) is named in
the module map, and every module the map names exists; the product imports
nothing of `studies/`."""

import re

from conftest import ROOT

PRODUCT = ("cortex", "common", "solver", "campaign", "analysis", "outputs")
TOP = (*PRODUCT, "studies")
PACKAGES = tuple(str(init.parent.relative_to(ROOT)) for top in TOP
                 for init in sorted((ROOT / top).rglob("__init__.py")))


def _modules():
    for package in PACKAGES:
        for path in sorted((ROOT / package).glob("*.py")):
            if path.name != "__init__.py":
                yield package, path.name


def test_the_readme_folder_map_is_the_tree():
    text = (ROOT / "README.md").read_text()
    section = text.split("## Architecture", 1)[1].split("\n## ", 1)[0]
    named = set(re.findall(r"^\| `([\w/.-]+)/` \|", section, flags=re.M))
    for folder in named:
        assert (ROOT / folder).is_dir(), f"README names {folder}/, which is not in the tree"
    tracked = {p.name for p in ROOT.iterdir() if p.is_dir() and not p.name.startswith(".")
               and p.name not in ("build", "results", "out") and not p.name.endswith(".egg-info")
               and any(p.rglob("*.*")) and p.name != "__pycache__"}
    assert tracked - named == set(), f"folders missing from the README's map: {sorted(tracked - named)}"


def test_every_module_is_in_the_module_map_and_every_named_module_exists():
    text = (ROOT / "docs" / "architecture.md").read_text()
    missing = [f"{package}/{name}" for package, name in _modules() if f"`{name}`" not in text
               and f"`{package}/{name}`" not in text]
    assert missing == [], f"modules not in docs/architecture.md: {missing}"
    everywhere = {name for package in PACKAGES for name in
                  (p.name for p in (ROOT / package).glob("*.py"))}
    ghosts = [token for token in re.findall(r"`([\w/]+\.py)`", text)
              if not ((ROOT / token).is_file() if "/" in token else token in everywhere)]
    assert ghosts == [], f"docs/architecture.md names modules that do not exist: {ghosts}"


def test_the_product_imports_nothing_of_the_studies():
    importing = [str(path.relative_to(ROOT)) for top in PRODUCT for path in sorted((ROOT / top).rglob("*.py"))
                 if re.search(r"^\s*(from|import)\s+studies\b", path.read_text(), flags=re.M)]
    assert importing == [], f"product modules that import studies/: {importing}"


def _imported_packages(package):
    """The top-level packages of TOP that the modules of `package` import (at module level or
    inside functions, `import x` and `from x import y` alike)."""
    import ast
    found = set()
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and node.module and not node.level
                     else [])
            found.update(n.split(".")[0] for n in names if n.split(".")[0] in TOP)
    return found - {package}


def test_the_engine_imports_nothing_of_analysis_and_the_package_map_has_no_cycle():
    """campaign/ knows no client (its task kinds are registered by their owners, `campaign.kinds`);
    the packages' imports form no cycle (a topological order exists)."""
    graph = {top: _imported_packages(top) for top in TOP}
    assert "analysis" not in graph["campaign"], "campaign/ imports analysis"
    assert "campaign" in graph["analysis"]            # the scan sees imports (analysis reads stores)
    order, left = [], dict(graph)
    while left:
        ready = [p for p, deps in left.items() if not deps - set(order)]
        assert ready, f"the packages import each other in a cycle: {left}"
        order += sorted(ready)
        left = {p: deps for p, deps in left.items() if p not in ready}
