"""How a result describes itself: one line for ``repr``, a small table for Jupyter.

A result class gives ``(label, value)`` rows; rows labelled ``"warning"`` are counted in the
line and listed in the table.
"""

from __future__ import annotations

import html

__all__ = ["summary_line", "summary_table"]


def summary_line(name: str, rows: list[tuple[str, str]]) -> str:
    """``Name(k=v, ..., N warning(s))``.

    Parameters
    ----------
    name : str
        The class name.
    rows : list of (str, str)
        Labels and values.

    Returns
    -------
    str
    """
    parts = [f"{k}={v}" for k, v in rows if k != "warning"]
    if len(parts) < len(rows):
        parts.append(f"{len(rows) - len(parts)} warning(s)")
    return f"{name}({', '.join(parts)})"


def summary_table(name: str, rows: list[tuple[str, str]]) -> str:
    """An HTML table of the rows, captioned with the class name.

    Parameters
    ----------
    name : str
        The class name.
    rows : list of (str, str)
        Labels and values.

    Returns
    -------
    str
    """
    cells = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                    f"<td style='text-align:left'>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table><caption>{html.escape(name)}</caption>{cells}</table>"
