"""Write docs/api.md from ``aeromag.__all__``: every public name, its module and summary.

Run ``python docs/make_api.py`` after adding a name to ``aeromag._API``.
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

import aeromag as am

HEADER = """# API

`import aeromag as am` gives every name below (listed in `am.__all__`; each is imported on
first use). Everything else is inside the packages or private. Generated from `am.__all__` by
`python docs/make_api.py`; the words are defined in `docs/conventions.md`.

| name | what it is | defined in |
|---|---|---|
"""


def summary(obj: object) -> str:
    """First line of the object's docstring (empty when it has none)."""
    doc = inspect.getdoc(obj) or ""
    if not callable(obj) and not inspect.isclass(obj):
        return ""
    return doc.strip().splitlines()[0].replace("|", "\\|") if doc.strip() else ""


def render() -> str:
    """The page."""
    rows = []
    for name in am.__all__:
        if name.startswith("__"):
            continue
        obj = getattr(am, name)
        where = am._API.get(name) or getattr(obj, "__module__", "aeromag")
        what = summary(obj) or ("constant" if not callable(obj) else "")
        rows.append(f"| `am.{name}` | {what} | `{where}` |")
    return HEADER + "\n".join(rows) + "\n"


if __name__ == "__main__":
    out = Path(__file__).with_name("api.md")
    out.write_text(render())
    sys.stdout.write(f"wrote {out}\n")
