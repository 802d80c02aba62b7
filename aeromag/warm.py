"""Import heavy libraries on a background thread while the main thread reads a log.

``scipy.signal`` alone takes most of a second to import, scikit-learn about as much again.
The command line starts :func:`warm_imports` before reading; pyarrow's CSV reader releases
the GIL, so the imports and the read overlap.  Library code never depends on this: every
module still imports what it uses, and an import already in progress on the background
thread is simply waited for (Python's per-module import locks).
"""

from __future__ import annotations

import importlib
import logging
import threading

log = logging.getLogger(__name__)


def warm_imports(*modules: str) -> threading.Thread:
    """Import ``modules`` in order on a daemon thread.

    Parameters
    ----------
    *modules : str
        Dotted module names (e.g. ``"scipy.signal"``).

    Returns
    -------
    threading.Thread
        The started thread (joining it is optional).
    """

    def run() -> None:
        for name in modules:
            try:
                importlib.import_module(name)
            except Exception as exc:  # the main thread's own import reports real problems
                log.debug("background import of %s failed: %s", name, exc)
                return

    th = threading.Thread(target=run, name="aeromag-warm-imports", daemon=True)
    th.start()
    return th
