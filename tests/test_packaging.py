"""Every third-party module the package imports is installed by ``pip install .``.

The README's first command installs the base dependencies only; an import of a package that
only an extra (or the test extra) installs would crash the main job on a fresh machine.
"""

from __future__ import annotations

import ast
import sys
import tomllib
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Optional features (module: extra, requirement in it), imported only inside the functions
#: that need them, with a message naming the extra to install.
OPTIONAL = {"h5py": ("hdf5", "h5py"), "distributed": ("dask", "dask"), "dask": ("dask", "dask"),
            "pyulog": ("ulog", "pyulog"),
            "pymavlink": ("dataflash", "pymavlink")}


def _requirement_names(reqs: list[str]) -> set[str]:
    out = set()
    for r in reqs:
        name = r.split(";")[0].split("[")[0]
        for sep in "<>=!~ ":
            name = name.split(sep)[0]
        out.add(name.strip().lower().replace("_", "-"))
    return out


def _imports() -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for path in (ROOT / "aeromag").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for n in names:
                top = n.split(".")[0]
                if top not in sys.stdlib_module_names and top not in ("aeromag", "__future__"):
                    found.setdefault(top, []).append(str(path.relative_to(ROOT)))
    return found


def test_every_imported_package_is_a_base_dependency_or_a_declared_extra():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    base = _requirement_names(meta["dependencies"])
    extras = {k: _requirement_names(v) for k, v in meta["optional-dependencies"].items()}
    dists = packages_distributions()
    for module, where in sorted(_imports().items()):
        names = {d.lower().replace("_", "-") for d in dists.get(module, [module])}
        if module in OPTIONAL:
            extra, req = OPTIONAL[module]
            assert req in extras[extra], (module, where)
            continue
        assert names & base, f"{module} (imported in {sorted(set(where))}) is not a base dependency"


@pytest.mark.parametrize("module", sorted(OPTIONAL))
def test_optional_packages_are_imported_only_inside_functions(module):
    for path in (ROOT / "aeromag").rglob("*.py"):
        for node in ast.parse(path.read_text()).body:  # module level only
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            assert not any(n.split(".")[0] == module for n in names), (path, module)
