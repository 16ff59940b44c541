"""The scenario schema's one building block: a section field with its validation and
documentation metadata (:func:`_key`), shared by every section of the file
(:mod:`.config`, :mod:`.truth`). Standard library only."""

from __future__ import annotations

from dataclasses import field


def _key(default, unit: str, doc: str, *, kind: str | None = None, low=None, high=None,
         low_inclusive: bool = False, high_inclusive: bool = True, choices=None, when=None,
         needs: str | None = None, allowed: str | None = None):
    """A schema entry: the field's default plus metadata for validation and documentation.

    ``kind`` is one of "real", "int", "str", "bool", "int_list", "real_list", "alpha",
    "n_elements" (inferred from the default when None). ``when`` = (other key, values) says the
    key applies only when that key of the same section has one of those values (setting it
    otherwise is a conflict); ``needs`` = other key says it applies only when that key of the
    same section is set (not None). ``allowed`` overrides the generated description of allowed
    values.
    """
    if kind is None:
        kind = {bool: "bool", str: "str", int: "int", float: "real"}[type(default)]
    meta = dict(unit=unit, doc=doc, kind=kind, low=low, high=high, low_inclusive=low_inclusive,
                high_inclusive=high_inclusive, choices=choices, when=when, needs=needs,
                allowed=allowed)
    return field(default=default, metadata=meta)
