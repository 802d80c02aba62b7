"""Fast paths give what the simple computation gives (issue 17).

Each test compares a vectorised or shortcut path with the plain computation it replaces, or
checks that a start-up shortcut leaves the library as it found it.
"""

from __future__ import annotations

import subprocess
import sys

_WARM = """
import scipy._lib._array_api as aa
orig = aa.FunctionDoc
from aeromag.cli.compensate import _warm
_warm(screen=True)
import scipy.signal
assert aa.FunctionDoc is orig, "scipy's docstring parser not put back"
doc = scipy.signal.butter.__doc__
assert "Array API Standard Support" in doc, "support note lost"
assert "\\n    Parameters\\n    ----------" in doc, "docstring re-parsed at import"
print("ok")
"""


def test_warm_imports_scipy_without_reparsing_its_docstrings() -> None:
    # A fresh interpreter: scipy.signal must not be imported yet.
    out = subprocess.run([sys.executable, "-c", _WARM], capture_output=True, text=True,
                         check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
