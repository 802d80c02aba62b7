"""Tests and README depend on nothing outside the repository except ../shared/ (issue 15 item 14).

The README's contract link points to docs/interface.md, the project's copy of
../shared/interface.md, which is kept equal to the shared page when that page is present.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
NOTE_END = "-->\n\n"


def test_tests_use_no_absolute_paths():
    bad = []
    pat = re.compile(r"""["'](/work/|/home/|/tmp/|/Users/|[A-Za-z]:\\)""")
    for f in sorted((ROOT / "tests").rglob("*.py")):
        for i, line in enumerate(f.read_text(encoding="utf-8").splitlines(), 1):
            if pat.search(line):
                bad.append(f"{f.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not bad, "absolute paths (use Path(__file__) or ../shared/):\n" + "\n".join(bad)


def test_readme_links_stay_inside_the_repository():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)", readme)
    local = [x for x in links if not re.match(r"[a-z]+:", x)]
    assert "docs/interface.md" in local
    for x in local:
        target = (ROOT / x).resolve()
        assert ROOT in target.parents or target == ROOT, f"README links outside the repo: {x}"
        assert target.exists(), f"README links to a missing file: {x}"


def test_docs_interface_is_the_shared_contract():
    ours = (ROOT / "docs" / "interface.md").read_text(encoding="utf-8")
    assert ours.startswith("<!-- The project's copy of the contract") and NOTE_END in ours
    body = ours.split(NOTE_END, 1)[1]
    assert body.startswith("# aeromag: the interface")
    shared = SHARED / "interface.md"
    if not shared.exists():
        pytest.skip("../shared/interface.md is absent: nothing to compare the copy with")
    assert body == shared.read_text(encoding="utf-8"), (
        "docs/interface.md differs from ../shared/interface.md: copy the shared page below the"
        " note")
