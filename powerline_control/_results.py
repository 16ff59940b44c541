"""The verbs the top-level results share, in one place: ``summary()``, ``to_dict()``,
``to_json()``, ``to_dataframe()`` where the result is a table, and a notebook display.

A result is a frozen dataclass; one that holds numpy arrays compares by identity
(``@dataclass(frozen=True, eq=False)``): ``a == a`` is True, a copy is another result, and ``==``
never raises (the ``__eq__`` a dataclass generates would ask ``bool(array == array)``). Compare
the numbers themselves (``np.allclose(a.states, b.states)``) to compare two results' values.

A result class inherits :class:`Result` (or :class:`TabularResult`, for one with a ``table()`` of
rows) and may override what it says better itself: most write their own ``summary()``; the
notebook display (``_repr_html_``) is a small HTML table of the summary's lines, so it shows what
``summary()`` says, escaped. ``to_json()`` is the text of ``to_dict()``: plain JSON types only (no
pickle), arrays as nested lists, a non-finite float as ``{"$float": "nan"}`` (``"inf"``,
``"-inf"``: standard JSON has neither), a complex number as ``{"real": ..., "imag": ...}``, and an
object that is not data (a LineModel, a StateSpace, a filter) by its type, ``{"$type": ...}``.
"""

from __future__ import annotations

import dataclasses
import enum
import html
import json
import math
import numbers
from collections.abc import Mapping
from pathlib import Path

import numpy as np

__all__ = ["Result", "TabularResult", "html_table", "plain", "summary_of", "to_dataframe"]

_MAX_HTML_ROWS = 60     # a notebook cell, not a report: longer summaries end with "... more"
_MAX_DEPTH = 12         # nested results deeper than this are named, not converted
_MAX_SUMMARY_ROWS = 12  # rows of a table shown by a tabular result's default summary


def plain(value: object, _depth: int = 0) -> object:
    """``value`` as plain JSON types (see the module docstring for the conventions)."""
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        value = float(value)
        return value if math.isfinite(value) else {"$float": repr(value)}
    if isinstance(value, numbers.Complex):
        return {"real": plain(value.real), "imag": plain(value.imag)}
    if isinstance(value, enum.Enum):
        return plain(value.value, _depth)
    if isinstance(value, Path):
        return str(value)
    if _depth > _MAX_DEPTH:
        return {"$type": type(value).__name__}
    if isinstance(value, np.ndarray):
        if np.iscomplexobj(value):
            return {"real": plain(value.real, _depth), "imag": plain(value.imag, _depth)}
        if value.dtype.kind in "biu" or (value.dtype.kind == "f" and np.isfinite(value).all()):
            return value.tolist()
        return [plain(item, _depth + 1) for item in value.tolist()] if value.ndim == 1 else \
            [plain(row, _depth + 1) for row in value]
    if hasattr(value, "to_dict") and callable(value.to_dict) and not isinstance(value, type):
        return plain(value.to_dict(), _depth + 1)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name), _depth + 1)
                for f in dataclasses.fields(value) if not f.name.startswith("_")}
    if isinstance(value, Mapping):
        return {str(key): plain(item, _depth + 1) for key, item in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [plain(item, _depth + 1) for item in value]
    return {"$type": type(value).__name__}


def _brief(value: object) -> str | None:
    """A field's value in a few words for a summary line; None to leave the field out."""
    if value is None:
        return None
    if isinstance(value, bool | np.bool_ | str):
        text = str(value)
        return text if len(text) <= 80 else text[:77] + "..."
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return f"{float(value):.6g}"
    if isinstance(value, np.ndarray):
        shape = " x ".join(str(n) for n in value.shape) or "scalar"
        if value.size and value.dtype.kind in "fiu" and np.isfinite(value).any():
            finite = value[np.isfinite(value)]
            return f"{shape} array, {finite.min():.4g} to {finite.max():.4g}"
        return f"{shape} {value.dtype} array"
    if isinstance(value, list | tuple) and len(value) <= 8 and all(
            isinstance(v, numbers.Real | str) for v in value):
        return "(" + ", ".join(_brief(v) or "" for v in value) + ")"
    if isinstance(value, list | tuple | Mapping):
        return f"{len(value)} item(s)"
    return type(value).__name__


def html_table(title: str, text: str) -> str:
    """A small HTML table of ``text``'s lines, with ``title`` as its caption; every text escaped.

    A line ``label: value`` is a row of two cells, a markdown table row (``| a | b |``) a row of
    its cells (its ``|---|`` rule left out), any other line one cell; blank lines are left out.

    Examples
    --------
    >>> print(html_table("R", "a: 1 < 2\\n| x | y |\\n|---|---|\\n| 1 | 2 |"))
    ... # doctest: +NORMALIZE_WHITESPACE
    <table class="powerline-control-result"><caption style="text-align: left">R</caption>
    <tr><th style="text-align: left">a</th><td style="text-align: left">1 &lt; 2</td></tr>
    <tr><td style="text-align: left">x</td><td style="text-align: left">y</td></tr>
    <tr><td style="text-align: left">1</td><td style="text-align: left">2</td></tr>
    </table>
    """
    rows = []
    lines = [line for line in text.splitlines() if line.strip()]
    for line in lines[:_MAX_HTML_ROWS]:
        stripped = line.strip()
        if stripped.startswith("|") and stripped.endswith("|"):
            cells = [cell.strip() for cell in stripped[1:-1].split("|")]
            if all(set(cell) <= set("-: ") for cell in cells):
                continue  # the markdown rule under a header
            rows.append("".join(_cell("td", cell) for cell in cells))
        elif ": " in stripped:
            label, value = stripped.split(": ", 1)
            rows.append(_cell("th", label) + _cell("td", value))
        else:
            rows.append(_cell("td", stripped, span=2))
    if len(lines) > _MAX_HTML_ROWS:
        rows.append(_cell("td", f"... {len(lines) - _MAX_HTML_ROWS} more line(s): see "
                                "summary()", span=2))
    body = "\n".join(f"<tr>{row}</tr>" for row in rows)
    return (f'<table class="powerline-control-result"><caption style="text-align: left">'
            f"{html.escape(title)}</caption>\n{body}\n</table>")


def _cell(tag: str, text: str, span: int = 1) -> str:
    colspan = f' colspan="{span}"' if span > 1 else ""
    return f'<{tag}{colspan} style="text-align: left">{html.escape(text)}</{tag}>'


def summary_of(numbers_by_key: Mapping) -> str:
    """A summary of a dict of headline numbers: one ``key: value`` line per scalar entry.

    Examples
    --------
    >>> print(summary_of({"length_m": 300.0, "rows": [1, 2], "ok": True}))
    length_m: 300
    ok: True
    """
    lines = []
    for key, value in numbers_by_key.items():
        if isinstance(value, bool | str | numbers.Real) and value is not None:
            lines.append(f"{key}: {_brief(value)}")
    return "\n".join(lines)


def to_dataframe(rows: list[dict], owner: str, columns: list | None = None):
    """``rows`` as a ``pandas.DataFrame``; pandas is optional, and its absence said clearly."""
    try:
        import pandas as pd
    except ImportError as error:  # pragma: no cover - pandas is installed where tested
        raise ImportError(
            f"{owner}.to_dataframe needs pandas (pip install 'powerline_control[pandas]'); "
            f"{owner}.table() gives the same rows as a list of dicts without it."
        ) from error
    return pd.DataFrame(rows, columns=columns)


class Result:
    """The verbs every top-level result shares (a mixin of the frozen result dataclasses).

    Examples
    --------
    >>> import json
    >>> import powerline_control as plc
    >>> traj = plc.plan_motion(start=0.2, target=1.8, limits=plc.RobotLimits(v_max=0.5, a_max=1.0))
    >>> json.loads(traj.to_json())["duration"] == traj.duration
    True
    >>> traj._repr_html_().startswith('<table class="powerline-control-result">')
    True
    """

    __slots__ = ()

    def summary(self) -> str:
        """A short text: one line ``field: value`` per field (arrays by shape and range).

        Returns
        -------
        str

        Examples
        --------
        >>> import powerline_control as plc
        >>> snap = plc.simulate(plc.LineModel(plc.Span.paper_lab(), n_elements=8),
        ...                     plc.HarmonicForce(1.0, 12.0, 1.0), duration=0.1, dt=1e-3)
        >>> print(snap.summary().splitlines()[0])
        t: 101 array, 0 to 0.1
        """
        lines = []
        for f in dataclasses.fields(self):
            if f.name.startswith("_") or not f.repr:
                continue
            text = _brief(getattr(self, f.name))
            if text is not None:
                lines.append(f"{f.name}: {text}")
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """The result as plain JSON types (arrays as lists), keyed by field name.

        Returns
        -------
        dict

        Examples
        --------
        >>> import powerline_control as plc
        >>> limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
        >>> sorted(plc.plan_motion(start=0.2, target=1.8, limits=limits).to_dict())[:3]
        ['acceleration', 'bounds', 'duration']
        """
        return {f.name: plain(getattr(self, f.name)) for f in dataclasses.fields(self)
                if not f.name.startswith("_")}

    def to_json(self, *, indent: int | None = None) -> str:
        """The result as JSON text: :meth:`to_dict` written out (no pickle; strict JSON).

        Parameters
        ----------
        indent : int, optional
            Indentation of the text (None: one line).

        Returns
        -------
        str

        Examples
        --------
        >>> import json
        >>> import powerline_control as plc
        >>> limits = plc.RobotLimits(v_max=0.5, a_max=1.0)
        >>> text = plc.plan_motion(start=0.2, target=1.8, limits=limits).to_json()
        >>> json.loads(text)["position"][-1]
        1.8
        """
        return json.dumps(plain(self.to_dict()), indent=indent, allow_nan=False)

    def _repr_html_(self) -> str:
        """The notebook display: :meth:`summary` as a small HTML table (escaped)."""
        return html_table(type(self).__name__, self.summary())


class TabularResult(Result):
    """A result whose numbers are a table (``table()``: a list of dicts, one per row).

    Examples
    --------
    >>> import powerline_control as plc
    >>> span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
    >>> sev = plc.aeolian_severity(span, wind_speeds=[2.0, 3.0])
    >>> sev.summary().splitlines()[0].startswith("| configuration | wind_speed |")
    True
    """

    __slots__ = ()

    def summary(self) -> str:
        """The table as markdown (its first rows; numbers to 4 significant digits).

        Returns
        -------
        str

        Examples
        --------
        >>> import powerline_control as plc
        >>> span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> print(plc.aeolian_severity(span, [2.0]).summary().splitlines()[2][:30])
        | no damper | 2 | 13.15 | 60 |
        """
        rows = self.table()
        if not rows:
            return f"{type(self).__name__}: no rows"
        columns = list(rows[0])
        lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        for row in rows[:_MAX_SUMMARY_ROWS]:
            lines.append("| " + " | ".join(_brief_cell(row.get(c)) for c in columns) + " |")
        if len(rows) > _MAX_SUMMARY_ROWS:
            lines.append(f"({len(rows) - _MAX_SUMMARY_ROWS} more row(s) in table())")
        return "\n".join(lines)

    def to_dataframe(self):
        """The table as a ``pandas.DataFrame`` (pandas is optional; this needs it installed).

        Returns
        -------
        pandas.DataFrame

        Examples
        --------
        >>> import powerline_control as plc
        >>> span = plc.Span.at_rts_fraction(300.0, "drake", 0.2)
        >>> try:                      # pandas is optional: without it, a clear ImportError
        ...     rows = len(plc.aeolian_severity(span, [2.0, 3.0]).to_dataframe())
        ... except ImportError as error:
        ...     rows = 2 if "needs pandas" in str(error) else None
        >>> rows
        2
        """
        return to_dataframe(self.table(), type(self).__name__)


def _brief_cell(value: object) -> str:
    if isinstance(value, numbers.Real) and \
            not isinstance(value, bool | np.bool_ | numbers.Integral):
        return f"{float(value):.4g}"
    return str(value)
