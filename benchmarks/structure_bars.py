"""Structure bars of issue 26, measured from the source: an audit independent of the tests.

Run by hand (or from ``tests/test_structure_bars.py``)::

    python benchmarks/structure_bars.py            # table; exit 1 when a bar fails
    python benchmarks/structure_bars.py --json     # the same, as JSON
    python benchmarks/structure_bars.py -v         # with every item behind each number

Every module of ``aeromag/`` is parsed with :mod:`ast` (nothing of the package is imported
except ``aeromag/__init__.py`` for ``__all__``, which imports only ``aeromag.errors``).  This
file shares no code with ``tests/test_architecture.py`` on purpose: two readings of the same
source that must agree.

What is counted, and how:

* **import graph**: every ``import x``, ``from x import y`` and relative import, wherever it
  stands (module level, inside functions, under ``if TYPE_CHECKING:``, in ``try``).  ``from p
  import m`` is an edge to ``p.m`` when that is a module, else to ``p``.  Python also runs the
  ``__init__`` of every parent package of what it imports; those implicit executions are not
  edges (each import is an edge to what it names).  Circles are the strongly connected
  components (Tarjan) with more than one module, plus modules importing themselves.  All
  edges count, a package's ``__init__`` importing its own modules included, so a module that
  imports its own package's facade while the facade imports it is a circle.  For information
  (``-v``) the circles are listed again with the implicit ``__init__`` runs as edges (those of
  packages other than the importer's own): such a circle made only of imports inside functions
  happens on call, never at import time.
* **private names**: ``from m import _x`` (``_x`` not a module, not a dunder) and ``m._x``
  where ``m`` is a bound aeromag module; the name is followed through re-exports to the module
  that defines it; unique ``(importer, defining module._x)`` pairs with importer != definer.
  Private *modules* (``aeromag._core``, ``plot._style``) are the package's layout, not counted.
* **allocator / GC tricks**: ``ctypes`` in any form, ``gc.freeze``/``gc.disable``/
  ``gc.set_threshold``, and the words ``mallopt``, ``malloc_trim``, ``trim_heap``, ``CDLL``,
  ``libc.so`` as names, attributes, definitions or strings (docstrings excepted).
* **forwarding modules**: a module whose body (docstring aside) is only imports, ``__all__``,
  aliases of imported names, ``del``, ``if TYPE_CHECKING:`` blocks and a lazy ``__getattr__``/
  ``__dir__``; or any module that warns ``DeprecationWarning`` from ``__getattr__`` or at
  import.  A package ``__init__`` is the real API of its subpackage, not a forward, when every
  name it imports comes from inside that subpackage, or when it is one of the public
  subpackages that ``aeromag/__init__.py`` lists in ``_SUBPACKAGES`` (a documented facade).
* **public API**: ``len(aeromag.__all__)``; each ``_API`` entry is checked (by ast) to be
  defined or imported by the module it names.
* **sequential filters**: every class with both a ``step`` and a ``run`` method; the return
  annotations are resolved through the module's imports (and re-exports) to their definition.
  The bar: all ``run`` return one type, ``aeromag._core.sequential.SequentialResult``, all
  ``step`` return ``aeromag._core.sequential.Step``, and the five named filters are among them.
* **private SciPy/NumPy**: an imported module path, an imported name or an attribute chain
  under ``scipy``/``numpy`` with a ``_private`` part.
* **thread pools**: ``ThreadPoolExecutor`` (and ``multiprocessing`` thread pools) outside
  ``aeromag/_core/parallel.py``; process pools and threads outside it are listed too and must
  be in :data:`ALLOWED_WORKERS`, each with its reason.
* **environment variables**: every ``AEROMAG_*`` word anywhere in the source text (code,
  comments, docstrings) and every f-string that builds one.
"""

from __future__ import annotations

import argparse
import ast
import importlib
import json
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PKG = "aeromag"

#: The filters issue 26 names: they must be found, with step() and run().
NAMED_FILTERS = {
    "aeromag._core.rls.RecursiveLeastSquares": "RLS",
    "aeromag.compensation.online.OnlineTL": "online TL",
    "aeromag.compass.calibration.CompassCalibration": "compass",
    "aeromag.nav.ukf.UnscentedKalmanFilter": "UKF",
    "aeromag.nav.filter.NavFilter": "UKF navigation",
    "aeromag._core.particles.ParticleFilter": "particle filter",
}
SEQUENTIAL = "aeromag._core.sequential"
PARALLEL = "aeromag._core.parallel"
ENV_OK = {"AEROMAG_THREADS"}
#: Process pools and threads allowed outside the parallel module (module -> reason).
ALLOWED_WORKERS = {
    "aeromag.workflows.batch_engines":
        "the batch command's one-process-per-log pool and its workers' watchdog thread"
        " (process isolation of the batch feature, not a compute thread pool)",
}
THREAD_POOLS = {"concurrent.futures.ThreadPoolExecutor",
                "concurrent.futures.thread.ThreadPoolExecutor",
                "multiprocessing.pool.ThreadPool", "multiprocessing.dummy.Pool"}
OTHER_WORKERS = {"concurrent.futures.ProcessPoolExecutor",
                 "concurrent.futures.process.ProcessPoolExecutor",
                 "multiprocessing.Pool", "multiprocessing.pool.Pool", "multiprocessing.Process",
                 "multiprocessing.get_context", "threading.Thread", "threading.Timer",
                 "_thread.start_new_thread", "joblib.Parallel", "os.fork"}
ALLOC_WORDS = ("mallopt", "malloc_trim", "trim_heap", "CDLL", "libc.so")
GC_TRICKS = {"gc.freeze", "gc.disable", "gc.set_threshold"}
REMOVED_TYPES = ("RLSResult", "PFResult", "StepResult", "FilterResult")


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


@dataclass
class Module:
    """One parsed module of the package."""

    name: str
    path: Path
    tree: ast.Module
    is_package: bool
    #: local name -> dotted name it is bound to by an import (anywhere in the module)
    bindings: dict[str, str] = field(default_factory=dict)
    #: (target module, line, where) for every import of a package module
    imports: list[tuple[str, int, str]] = field(default_factory=list)

    #: every node of the tree (walked once)
    nodes: list[ast.AST] = field(default_factory=list)
    #: path relative to the tree's root, for messages
    rel: str = ""


def discover(root: Path = ROOT) -> dict[str, Module]:
    """Every module below ``root/aeromag``, parsed, with its imports resolved."""
    mods: dict[str, Module] = {}
    for path in sorted((root / PKG).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts.pop()
        name = ".".join(parts)
        tree = ast.parse(path.read_text(), str(path))
        mods[name] = Module(name, path, tree, is_pkg, nodes=list(ast.walk(tree)),
                            rel=str(path.relative_to(root)))
    for m in mods.values():
        _read_imports(m, mods)
    return mods


def _absolute(m: Module, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = m.name.split(".")
    if not m.is_package:
        base.pop()
    if node.level > 1:
        base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _nearest(name: str, mods: dict[str, Module]) -> str | None:
    while name not in mods:
        if "." not in name:
            return None
        name = name.rsplit(".", 1)[0]
    return name


def _places(m: Module) -> dict[int, str]:
    """Line -> ``function`` or ``type_checking`` for the lines inside those (else module)."""
    out: dict[int, str] = {}
    for node in m.nodes:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
            for line in range(node.lineno, (node.end_lineno or node.lineno) + 1):
                out.setdefault(line, "function")
    for node in m.nodes:  # a TYPE_CHECKING block says more than the function around it
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for sub in node.body:
                for line in range(sub.lineno, (sub.end_lineno or sub.lineno) + 1):
                    out[line] = "type_checking"
    return out


def _read_imports(m: Module, mods: dict[str, Module]) -> None:
    seen = set()
    places = _places(m)
    for node in m.nodes:
        targets: list[str] = []
        if isinstance(node, ast.Import):
            for a in node.names:
                targets.append(a.name)
                if a.asname:
                    m.bindings[a.asname] = a.name
                else:
                    top = a.name.split(".")[0]
                    m.bindings[top] = top
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(m, node)
            for a in node.names:
                if a.name == "*":
                    targets.append(base)
                    continue
                m.bindings[a.asname or a.name] = f"{base}.{a.name}"
                sub = f"{base}.{a.name}"
                targets.append(sub if sub in mods else base)
        for t in targets:
            if t != PKG and not t.startswith(PKG + "."):
                continue
            target = _nearest(t, mods)
            if target is None:
                continue
            key = (target, node.lineno, places.get(node.lineno, "module"))
            if key not in seen:
                seen.add(key)
                m.imports.append(key)


def _dotted(m: Module, node: ast.AST) -> str | None:
    """The dotted name an expression ``a.b.c`` stands for, through the module's imports."""
    if isinstance(node, ast.Name):
        return m.bindings.get(node.id)
    if isinstance(node, ast.Attribute):
        head = _dotted(m, node.value)
        return f"{head}.{node.attr}" if head else None
    return None


def _docstrings(m: Module) -> set[int]:
    out = set()
    for node in m.nodes:
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                out.add(id(body[0].value))
    return out


def _defines(m: Module, name: str) -> bool:
    for node in m.tree.body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) \
                and node.name == name:
            return True
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        for t in targets:
            if any(isinstance(n, ast.Name) and n.id == name for n in ast.walk(t)):
                return True
    return False


def definition(mods: dict[str, Module], dotted: str, depth: int = 0) -> str:
    """``module.name`` where a name is defined, following re-exports (``from x import name``)."""
    mod, _, name = dotted.rpartition(".")
    if mod not in mods or depth > 10 or _defines(mods[mod], name):
        return dotted
    bound = mods[mod].bindings.get(name)
    if bound and (bound == PKG or bound.startswith(PKG + ".")) and bound != dotted:
        return definition(mods, bound, depth + 1)
    return dotted


# --------------------------------------------------------------------------- the bars
def tarjan(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one node (recursive Tarjan)."""
    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    comps: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return sorted(comps)


def bar_cycles(mods: dict[str, Module]) -> dict:
    edges = {n: {t for t, _, _ in m.imports} for n, m in mods.items()}
    self_loops = sorted(n for n, e in edges.items() if n in e)
    comps = tarjan({n: e - {n} for n, e in edges.items()})
    kinds: dict[str, int] = {}
    for m in mods.values():
        for _, _, where in m.imports:
            kinds[where] = kinds.get(where, 0) + 1
    # Informative: with the parent packages' __init__ that an import runs (those of another
    # package than the importer's own), a circle of imports made on call (in functions) shows.
    def parents(n: str) -> set[str]:
        parts = n.split(".")
        return {".".join(parts[:i]) for i in range(1, len(parts))}

    run_too = {n: (e | {p for t in e for p in parents(t) if p in mods} - parents(n)) - {n}
               for n, e in edges.items()}
    return {"measured": len(comps) + len(self_loops), "limit": 0,
            "items": [" <-> ".join(c) for c in comps] + [f"{n} imports itself" for n in self_loops],
            "detail": {"modules": len(mods), "edges": sum(len(e) for e in edges.values()),
                       "import statements by place": kinds,
                       "circles counting the parents' __init__ an import runs":
                           [" <-> ".join(c) for c in tarjan(run_too)]}}


def bar_private_names(mods: dict[str, Module]) -> dict:
    pairs: dict[tuple[str, str], str] = {}
    for m in mods.values():
        for node in m.nodes:
            found: list[str] = []
            if isinstance(node, ast.ImportFrom):
                base = _absolute(m, node)
                if base == PKG or base.startswith(PKG + "."):
                    found = [f"{base}.{a.name}" for a in node.names
                             if _private(a.name) and f"{base}.{a.name}" not in mods]
            elif isinstance(node, ast.Attribute) and _private(node.attr):
                head = _dotted(m, node.value)
                if head in mods and f"{head}.{node.attr}" not in mods:
                    found = [f"{head}.{node.attr}"]
            for dotted in found:
                where = definition(mods, dotted)
                if where.rpartition(".")[0] != m.name:
                    pairs.setdefault((m.name, where), f"{m.rel}:{node.lineno}")
    items = [f"{imp} -> {name}  ({loc})" for (imp, name), loc in sorted(pairs.items())]
    return {"measured": len(pairs), "limit": 15, "items": items}


def bar_allocator(mods: dict[str, Module]) -> dict:
    hits = set()
    for m in mods.values():
        docs = _docstrings(m)
        for node in m.nodes:
            word = None
            if isinstance(node, ast.alias):
                word = node.name
            elif isinstance(node, ast.Name):
                word = node.id
            elif isinstance(node, ast.Attribute):
                dotted = _dotted(m, node)
                if dotted in GC_TRICKS:
                    hits.add(f"{m.rel}:{node.lineno}: {dotted}")
                word = node.attr
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                word = node.name
            elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                    and id(node) not in docs:
                word = node.value
            if word and (word.split(".")[0] == "ctypes" or any(w in word for w in ALLOC_WORDS)):
                hits.add(f"{m.rel}:{getattr(node, 'lineno', '?')}: {word[:60]!r}")
    return {"measured": len(hits), "limit": 0, "items": sorted(hits)}


def _is_reexport_stmt(m: Module, node: ast.stmt) -> bool:
    if isinstance(node, ast.Import | ast.ImportFrom | ast.Delete | ast.Pass):
        return True
    if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
        return True  # docstring
    if isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign):
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        if all(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            return True
        return isinstance(node.value, ast.Name | ast.Attribute) and _dotted(m, node.value) \
            is not None  # an alias of an imported name
    if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
        return True
    if isinstance(node, ast.Try):
        return all(_is_reexport_stmt(m, s) for s in node.body)
    return isinstance(node, ast.FunctionDef) and node.name in ("__getattr__", "__dir__")


def _warns_deprecation(m: Module) -> bool:
    scopes: list[ast.AST] = [s for s in m.tree.body if not isinstance(
        s, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)]
    scopes += [s for s in m.tree.body if isinstance(s, ast.FunctionDef)
               and s.name == "__getattr__"]
    return any(isinstance(n, ast.Name | ast.Attribute) and "DeprecationWarning" in ast.unparse(n)
               for s in scopes for n in ast.walk(s))


def _public_subpackages(mods: dict[str, Module]) -> set[str]:
    for node in mods[PKG].tree.body:
        if isinstance(node, ast.AnnAssign | ast.Assign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "_SUBPACKAGES" for t in targets):
                return {f"{PKG}.{v}" for v in ast.literal_eval(node.value)}
    return set()


def bar_forwarding(mods: dict[str, Module]) -> dict:
    facades = _public_subpackages(mods)
    items, apis = [], []
    for m in mods.values():
        body = m.tree.body
        has_import = any(isinstance(s, ast.Import | ast.ImportFrom) for s in body)
        only_forwards = has_import and all(_is_reexport_stmt(m, s) for s in body)
        if _warns_deprecation(m):
            items.append(f"{m.rel}: warns DeprecationWarning at import or from __getattr__")
        elif only_forwards and not m.is_package:
            items.append(f"{m.rel}: only imports and re-exports")
        elif only_forwards:
            outside = sorted({t for t, _, _ in m.imports
                              if t != m.name and not t.startswith(m.name + ".")})
            if not outside:
                apis.append(f"{m.name} (its own modules)")
            elif m.name in facades:
                apis.append(f"{m.name} (public facade in aeromag._SUBPACKAGES: {outside})")
            else:
                items.append(f"{m.rel}: package re-exporting other packages {outside}")
    return {"measured": len(items), "limit": 0, "items": items,
            "detail": {"package APIs (not forwards)": apis}}


def bar_public_api(mods: dict[str, Module]) -> dict:
    sys.path.insert(0, str(mods[PKG].path.parents[1]))
    try:
        am = importlib.import_module(PKG)
    finally:
        sys.path.pop(0)
    names = list(am.__all__)
    problems = [f"{n} twice in __all__" for n in sorted({n for n in names if names.count(n) > 1})]
    for name, where in getattr(am, "_API", {}).items():
        if where not in mods:
            problems.append(f"{name}: module {where} not found")
        elif not (_defines(mods[where], name) or name in mods[where].bindings):
            problems.append(f"{name}: {where} neither defines nor imports it")
    return {"measured": len(names), "limit": 45, "items": problems, "ok": not problems,
            "detail": {"loaded modules": sorted(k for k in sys.modules if k.startswith(PKG))}}


def _annotation(m: Module, mods: dict[str, Module], node: ast.expr | None) -> str:
    if node is None:
        return "(none)"
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        node = ast.parse(node.value, mode="eval").body
    if isinstance(node, ast.Name) and _defines(m, node.id):
        return f"{m.name}.{node.id}"
    dotted = _dotted(m, node)
    return definition(mods, dotted) if dotted else ast.unparse(node)


def bar_sequential(mods: dict[str, Module]) -> dict:
    filters, others = {}, []
    for m in mods.values():
        for cls in m.nodes:
            if not isinstance(cls, ast.ClassDef):
                continue
            meth = {f.name: f for f in cls.body if isinstance(f, ast.FunctionDef)}
            if "run" in meth and "step" in meth:
                filters[f"{m.name}.{cls.name}"] = {
                    "run": _annotation(m, mods, meth["run"].returns),
                    "step": _annotation(m, mods, meth["step"].returns)}
            elif "run" in meth:
                ret = _annotation(m, mods, meth["run"].returns)
                others.append(f"{m.name}.{cls.name}.run -> {ret} (no step: not a filter)")
    run_types = sorted({f["run"] for f in filters.values()})
    items = [f"{k}: run -> {v['run']}, step -> {v['step']}" for k, v in sorted(filters.items())]
    missing = sorted(set(NAMED_FILTERS) - set(filters))
    ok = (run_types == [f"{SEQUENTIAL}.SequentialResult"] and not missing
          and all(f["step"] == f"{SEQUENTIAL}.Step" for f in filters.values()))
    return {"measured": len(run_types), "limit": 1, "items": items, "ok": ok,
            "detail": {"run() types": run_types, "named filters missing": missing,
                       "other run() methods": others}}


def bar_private_numerics(mods: dict[str, Module]) -> dict:
    hits = set()
    for m in mods.values():
        for node in m.nodes:
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Attribute):
                names = [_dotted(m, node) or ""]
            for n in names:
                parts = n.split(".")
                if parts[0] in ("scipy", "numpy") and any(_private(p) for p in parts[1:]):
                    hits.add(f"{m.rel}:{node.lineno}: {n}")
    return {"measured": len(hits), "limit": 0, "items": sorted(hits)}


def _uses(m: Module, wanted: set[str]) -> set[str]:
    out = set()
    for node in m.nodes:
        if isinstance(node, ast.ImportFrom) and not node.level:
            out |= {f"{node.module}.{a.name}" for a in node.names} & wanted
        elif isinstance(node, ast.Name | ast.Attribute):
            dotted = _dotted(m, node)
            if dotted in wanted:
                out.add(dotted)
    return out


def bar_thread_pools(mods: dict[str, Module]) -> dict:
    items = [f"{m.rel}: {sorted(used)}" for m in mods.values() if m.name != PARALLEL
             and (used := _uses(m, THREAD_POOLS))]
    return {"measured": len(items), "limit": 0, "items": items,
            "detail": {"in the parallel module": sorted(_uses(mods[PARALLEL], THREAD_POOLS))}}


def bar_other_workers(mods: dict[str, Module]) -> dict:
    items, allowed = [], []
    for m in mods.values():
        used = _uses(m, OTHER_WORKERS)
        if m.name == PARALLEL or not used:
            continue
        line = f"{m.rel}: {sorted(used)}"
        if m.name in ALLOWED_WORKERS:
            allowed.append(f"{line}: {ALLOWED_WORKERS[m.name]}")
        else:
            items.append(line)
    return {"measured": len(items), "limit": 0, "items": items,
            "detail": {"allowed": allowed}}


def bar_env(mods: dict[str, Module]) -> dict:
    names: dict[str, list[str]] = {}
    built = []
    for m in mods.values():
        for i, line in enumerate(m.path.read_text().splitlines(), 1):
            for w in re.findall(r"AEROMAG_[A-Za-z0-9_]*", line):
                names.setdefault(w, []).append(f"{m.rel}:{i}")
        for node in m.nodes:
            if isinstance(node, ast.JoinedStr) and node.values and isinstance(
                    node.values[0], ast.Constant) and str(node.values[0].value).endswith(
                    "AEROMAG_"):
                built.append(f"{m.rel}:{node.lineno}: f-string builds an AEROMAG_ name")
    bad = sorted(set(names) - ENV_OK)
    return {"measured": len(names), "limit": 1,
            "items": [f"{n}: {names[n]}" for n in bad] + built, "ok": not bad and not built,
            "detail": {n: v for n, v in sorted(names.items())}}


def bar_removed_types(mods: dict[str, Module]) -> dict:
    word = re.compile(r"\b(" + "|".join(REMOVED_TYPES) + r")\b")
    hits = [f"{m.rel}:{i}: {w}" for m in mods.values()
            for i, line in enumerate(m.path.read_text().splitlines(), 1)
            for w in word.findall(line)]
    return {"measured": len(hits), "limit": 0, "items": hits}


BARS = {
    "import cycles (all imports)": bar_cycles,
    "private names across modules": bar_private_names,
    "allocator/GC tricks": bar_allocator,
    "forwarding modules": bar_forwarding,
    "names in aeromag.__all__": bar_public_api,
    "run() result types of the filters": bar_sequential,
    "private SciPy/NumPy APIs": bar_private_numerics,
    "thread pools outside _core/parallel": bar_thread_pools,
    "processes/threads outside it, unlisted": bar_other_workers,
    "AEROMAG_* environment variables": bar_env,
    "removed result types still named": bar_removed_types,
}


def measure(root: Path = ROOT) -> dict[str, dict]:
    """Every bar: ``{name: {"measured", "limit", "ok", "items", "detail"}}``."""
    mods = discover(root)
    out = {}
    for name, fn in BARS.items():
        res = fn(mods)
        res["ok"] = res.get("ok", True) and res["measured"] <= res["limit"]
        out[name] = res
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="machine output (JSON)")
    ap.add_argument("-v", "--verbose", action="store_true", help="list the items of every bar")
    ap.add_argument("--root", type=Path, default=ROOT,
                    help="the tree holding aeromag/ (default: this checkout)")
    args = ap.parse_args(argv)
    res = measure(args.root)
    ok = all(r["ok"] for r in res.values())
    if args.json:
        print(json.dumps({"ok": ok, "bars": res}, indent=2, default=str))
        return 0 if ok else 1
    width = max(map(len, res))
    print(f"{'bar':<{width}}  {'measured':>8}  {'limit':>5}  result")
    for name, r in res.items():
        print(f"{name:<{width}}  {r['measured']:>8}  {'<= ' + str(r['limit']):>5}  "
              f"{'pass' if r['ok'] else 'FAIL'}")
        if args.verbose or not r["ok"]:
            for item in r["items"]:
                print(f"    {item}")
            if args.verbose:
                for k, v in r.get("detail", {}).items():
                    print(f"    [{k}] {v}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
