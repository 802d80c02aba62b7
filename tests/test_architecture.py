"""The package's shape: imports run one way (by layer), no import circle, small modules.

Layers, bottom to top (``shared/architecture.md``)::

    errors, conventions -> _core -> domain packages -> plot -> workflows -> cli

* ``io`` (everything that touches a file) is used only by ``workflows`` and ``cli``;
* domain packages import ``_core``, ``errors``, ``conventions`` and, across domains, only
  qc -> compensation, track -> detection/nav, detection -> nav;
* ``synthetic`` (the simulators, the tests' oracles) imports no fitting or filtering code;
* every module belongs to a layer: no old flat module forwarding to the new layout.

Imports are read with :mod:`ast` from every module, function-level imports included;
imports under ``if TYPE_CHECKING:`` count too, for the directions and for circles (a type
that two modules need lives one level below both).  Private names (``_name``) imported from
another module are counted and kept few (make them public in their module, or move the
code); a module above :data:`MAX_LINES` lines is a warning, not a failure (split by concept,
never to get under a number).
"""

from __future__ import annotations

import ast
import warnings
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "aeromag"

#: Layer of each top-level part of the package (higher may import lower).
LAYERS: dict[str, int] = {
    "errors": 0, "conventions": 0,
    "_core": 1,
    "compensation": 2, "compass": 2, "nav": 2, "detection": 2, "qc": 2, "track": 2,
    "synthetic": 2, "survey": 2,
    "estimation": 2,  # public facade: re-exports the generic filters of _core (and nav's UKF)
    "io": 2,  # beside the domains: it may use _core; who may use it is checked separately
    "plot": 3,
    "workflows": 4,
    "cli": 5, "__main__": 5,
}
DOMAINS = {"compensation", "compass", "nav", "detection", "qc", "track", "synthetic", "survey"}
#: Cross-domain imports allowed (importer -> imported).
CROSS = {("qc", "compensation"), ("track", "detection"), ("track", "nav"),
         ("detection", "nav")}
#: What the simulators must never import.
NOT_IN_SYNTHETIC = ("aeromag.compensation", "aeromag.compass", "aeromag.nav",
                    "aeromag.detection", "aeromag.qc", "aeromag.track", "aeromag.survey",
                    "aeromag._core.lstsq",
                    "aeromag._core.filters", "aeromag._core.rls", "aeromag._core.unscented",
                    "aeromag._core.particles", "aeromag._core.fit_diagnostics",
                    "aeromag._core.decimate")
#: Lines above which a module is worth a look (a warning; the CLI option table is a table).
MAX_LINES = 600
#: Most private names imported across modules (``from aeromag.x import _name``).
MAX_PRIVATE_IMPORTS = 15
LONG_OK = {"aeromag.cli._options"}


def _part(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _modules() -> dict[str, Path]:
    mods = {}
    for path in sorted(PKG.rglob("*.py")):
        parts = path.relative_to(PKG.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = path
    return mods


MODULES = _modules()

#: Allowed exceptions, each with its reason.
ALLOWED: dict[tuple[str, str], str] = {
    ("aeromag.compensation.model", "aeromag.io.model_file"):
        "TLModel.load: the model's file method reads through io's validated reader, on call",
    ("aeromag.compensation.model", "aeromag.io"):
        "TLModel.save: the model's file method writes through io's atomic writer, on call",
}

#: Violations that their owners still have open (module -> imported module).  The tests
#: tolerate them and warn about entries that are fixed (delete those lines).  Add nothing here.
KNOWN_OPEN: set[tuple[str, str]] = set()
#: Circles their owners still have open (same rule: the list only shrinks).
KNOWN_CIRCLES: list[list[str]] = []


def _is_package(mod: str) -> bool:
    return MODULES[mod].name == "__init__.py"


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for sub in node.body:
                for n in ast.walk(sub):
                    if hasattr(n, "lineno"):
                        lines.add(n.lineno)
    return lines


def _resolve(mod: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = mod.split(".") if _is_package(mod) else mod.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def imports_of(mod: str) -> list[tuple[str, int, bool]]:
    """``(imported aeromag module, line, runs)`` for every import in module ``mod``."""
    tree = ast.parse(MODULES[mod].read_text())
    typing_only = _type_checking_lines(tree)
    out: list[tuple[str, int, bool]] = []
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(mod, node)
            for a in node.names:  # "from pkg import submodule" imports the submodule
                sub = f"{base}.{a.name}"
                targets.append(sub if sub in MODULES else base)
        for t in targets:
            if t == "aeromag" or t.startswith("aeromag."):
                while t not in MODULES and "." in t:
                    t = t.rsplit(".", 1)[0]
                item = (t, node.lineno, node.lineno not in typing_only)
                if item not in out:
                    out.append(item)
    return out


def _violation(importer: str, imported: str) -> str | None:
    """Why ``importer`` may not import ``imported`` (None when it may)."""
    a, b = _part(importer), _part(imported)
    if a == "__init__" or b == "__init__" or a == b:
        return None
    if a not in LAYERS or b not in LAYERS:
        return f"{a if a not in LAYERS else b} has no layer in tests/test_architecture.py"
    if b == "io" and LAYERS[a] < LAYERS["workflows"]:
        return "only workflows and cli may use aeromag.io (files)"
    if a == "synthetic" and imported.startswith(NOT_IN_SYNTHETIC):
        return "the simulators (oracles) must not import fitting or filtering code"
    if a in DOMAINS and b in DOMAINS and (a, b) not in CROSS:
        return f"cross-domain import {a} -> {b} (allowed: {sorted(CROSS)})"
    if LAYERS[b] > LAYERS[a]:
        return f"imports upward ({a}, layer {LAYERS[a]} -> {b}, layer {LAYERS[b]})"
    return None


def test_every_part_has_a_layer():
    parts = {_part(m) for m in MODULES} - {"__init__"}
    assert parts <= set(LAYERS), f"add a layer for {sorted(parts - set(LAYERS))}"


def _violations() -> list[tuple[str, str, str]]:
    """``(module, imported, "file:line: why")`` for every import against the rules."""
    out = []
    for mod in MODULES:
        for target, line, _ in imports_of(mod):
            why = _violation(mod, target)
            if why and (mod, target) not in ALLOWED:
                out.append((mod, target, f"{MODULES[mod].relative_to(PKG.parent)}:{line}:"
                                         f" {mod} -> {target}: {why}"))
    return out


def test_imports_run_downward():
    found = _violations()
    bad = [msg for mod, target, msg in found if (mod, target) not in KNOWN_OPEN]
    fixed = sorted(KNOWN_OPEN - {(mod, target) for mod, target, _ in found})
    if fixed:
        warnings.warn(f"fixed: delete {fixed} from KNOWN_OPEN (tests/test_architecture.py)",
                      stacklevel=1)
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        x = stack.pop()
                        on.discard(x)
                        comp.append(x)
                        if x == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
            elif w not in index:
                index[w] = low[w] = counter
                counter += 1
                stack.append(w)
                on.add(w)
                work.append((w, iter(sorted(edges.get(w, ())))))
            elif w in on:
                low[v] = min(low[v], index[w])
    return out


def test_no_import_circle():
    # Every edge counts, a package's __init__ importing its own modules included: a module
    # that imports its package's facade while the facade imports it is a circle.
    edges = {m: {t for t, _, _runs in imports_of(m) if t != m} for m in MODULES}
    found = _cycles(edges)
    circles = [c for c in found if c not in KNOWN_CIRCLES]
    fixed = [c for c in KNOWN_CIRCLES if c not in found]
    if fixed:
        warnings.warn(f"fixed: remove {fixed} from KNOWN_CIRCLES in tests/test_architecture.py",
                      stacklevel=1)
    assert not circles, "import circles:\n" + "\n".join(" <-> ".join(c) for c in circles)


def test_the_checker_catches_what_it_should():
    assert _violation("aeromag.compensation.fit", "aeromag.qc.quality")
    assert _violation("aeromag.compensation.fit", "aeromag.plot.compensation")
    assert _violation("aeromag._core.filters", "aeromag.compensation.config")
    assert _violation("aeromag.compensation.model", "aeromag.io.json")
    assert _violation("aeromag.synthetic.physics", "aeromag.compensation.terms")
    assert _violation("aeromag.synthetic.physics", "aeromag._core.filters")
    assert _violation("aeromag.qc.quality", "aeromag.workflows.report")
    assert _violation("aeromag.workflows.batch", "aeromag.compensate")  # no layer
    assert _violation("aeromag.qc.quality", "aeromag.compensation.config") is None
    assert _violation("aeromag.workflows.compensate", "aeromag.io") is None
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def _lines(mod: str) -> int:
    return len(MODULES[mod].read_text().splitlines())


@pytest.mark.parametrize("mod", sorted(set(MODULES) - LONG_OK))
def test_modules_stay_small(mod):
    n = _lines(mod)
    if n > MAX_LINES:
        warnings.warn(f"{MODULES[mod].relative_to(PKG.parent)}: {n} lines > {MAX_LINES}: does"
                      " it hold two concepts?", stacklevel=1)


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def private_imports() -> list[str]:
    """``module -> source._name`` for every private name of another module it uses.

    Both ``from aeromag.x import _name`` and ``x._name`` on a module bound by an import
    (``from aeromag import x``, ``import aeromag.x as x``) count, wherever they stand.
    """
    out = []
    for mod, path in MODULES.items():
        tree = ast.parse(path.read_text())
        bound: dict[str, str] = {}  # local name -> aeromag module it stands for
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = _resolve(mod, node)
                bound.update({a.asname or a.name: f"{base}.{a.name}" for a in node.names
                              if f"{base}.{a.name}" in MODULES})
            elif isinstance(node, ast.Import):
                bound.update({a.asname: a.name for a in node.names
                              if a.asname and a.name in MODULES})
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = _resolve(mod, node)
                if base == "aeromag" or base.startswith("aeromag."):
                    out += [f"{mod} -> {base}.{a.name}" for a in node.names
                            if _private(a.name) and f"{base}.{a.name}" not in MODULES]
            elif (isinstance(node, ast.Attribute) and _private(node.attr)
                  and isinstance(node.value, ast.Name) and node.value.id in bound
                  and f"{bound[node.value.id]}.{node.attr}" not in MODULES
                  and bound[node.value.id] != mod):
                out.append(f"{mod} -> {bound[node.value.id]}.{node.attr}")
    return out


def test_few_private_names_cross_modules():
    found = private_imports()
    assert len(found) <= MAX_PRIVATE_IMPORTS, (
        f"{len(found)} private names imported across modules (at most"
        f" {MAX_PRIVATE_IMPORTS}): make them public in their module or move the code:\n"
        + "\n".join(found))


def _forwards_only(tree: ast.Module) -> bool:
    """Whether a module's body is only imports, ``__all__`` and a docstring (a forward)."""
    body = [n for n in tree.body if not (isinstance(n, ast.Expr)
                                         and isinstance(n.value, ast.Constant))]
    return bool(body) and all(
        isinstance(n, ast.Import | ast.ImportFrom)
        or (isinstance(n, ast.Assign | ast.AnnAssign | ast.AugAssign)
            and all(isinstance(t, ast.Name) and t.id == "__all__"
                    for t in (n.targets if isinstance(n, ast.Assign) else [n.target])))
        for n in body)


def test_no_forwarding_module():
    """A module that only re-exports another is an old path kept alive: import the real one.

    Package ``__init__`` files are the API of their package and may re-export its modules.
    """
    found = [str(MODULES[m].relative_to(PKG.parent)) for m in MODULES
             if not _is_package(m) and _forwards_only(ast.parse(MODULES[m].read_text()))]
    assert not found, f"forwarding modules (import from the defining module): {found}"


def test_the_private_and_forward_checks_catch_what_they_should():
    assert _forwards_only(ast.parse('"""Doc."""\nfrom ._app import app\n__all__ = ["app"]\n'))
    assert not _forwards_only(ast.parse("from ._app import app\n\n\ndef f():\n    pass\n"))
