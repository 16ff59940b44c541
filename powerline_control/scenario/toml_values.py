"""Values written as TOML: strings with their escapes, numbers that read back equal, lists,
tables and keys (Python's ``tomllib`` reads TOML; it does not write it).

Used by the template (:mod:`.template`) and by
:func:`~powerline_control.scenario.override_scenario_text`, which writes the keys it overrides.
"""

from __future__ import annotations

import numbers
import re
from collections.abc import Mapping

import numpy as np

from ..errors import InputError

__all__ = ["toml_value", "toml_string", "toml_key"]


def toml_value(value: object) -> str:
    r"""A Python value as TOML text that :mod:`tomllib` reads back equal.

    Strings become basic strings with every character TOML reserves escaped (``"``, ``\``,
    control characters: :func:`toml_string`), numbers are written with ``repr`` (every float
    bit-exact, ``nan`` and ``inf`` as TOML spells them), booleans lower case, sequences as
    arrays and mappings as inline tables.

    Parameters
    ----------
    value : str, bool, int, float, sequence or mapping
        The value.

    Returns
    -------
    str

    Raises
    ------
    InputError
        For a value TOML cannot hold (``None``, an object, a string with a lone surrogate).

    Examples
    --------
    >>> print(toml_value(r'the "B" line in C:\new'))
    "the \"B\" line in C:\\new"
    >>> import tomllib
    >>> tomllib.loads("v = " + toml_value([0.1, float("nan"), "tab\there"]))["v"]
    [0.1, nan, 'tab\there']
    """
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return repr(int(value))
    if isinstance(value, numbers.Real):
        return repr(float(value))   # the shortest text that reads back bit-exact; nan, inf
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}"
                               for k, v in value.items()) + "}"
    if isinstance(value, tuple | list | np.ndarray):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise InputError(f"A scenario value must be a string, a number, a boolean, a list or a "
                     f"table to be written as TOML. Got {value!r:.60} of type "
                     f"{type(value).__name__}.")


# TOML's short escapes; every other control character is written \uXXXX.
_SHORT_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n",
                  "\f": "\\f", "\r": "\\r"}


def toml_string(text: str) -> str:
    r"""``text`` as a TOML basic string: the one place TOML strings are escaped.

    TOML forbids a raw ``"``, ``\`` or control character (U+0000-U+001F, U+007F) inside a
    basic string; each is escaped, everything else (any Unicode) is written as is. A lone
    surrogate (no Unicode character; a UTF-8 file cannot hold it) is refused.

    Parameters
    ----------
    text : str
        The string.

    Returns
    -------
    str
        The quoted string.

    Raises
    ------
    InputError
        ``text`` holds a lone surrogate.

    Examples
    --------
    >>> print(toml_string(r"C:\runs\b"), toml_string("bell\x07"))
    "C:\\runs\\b" "bell\u0007"
    """
    out = []
    for char in text:
        code = ord(char)
        if char in _SHORT_ESCAPES:
            out.append(_SHORT_ESCAPES[char])
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        elif 0xD800 <= code <= 0xDFFF:
            raise InputError(f"The string {text!r:.60} holds a lone surrogate (U+{code:04X}), "
                             "which is not a Unicode character: TOML (and a UTF-8 file) cannot "
                             "hold it.")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def toml_key(key: object) -> str:
    """A TOML key: bare when it is only letters, digits, ``_`` and ``-``, else quoted.

    Parameters
    ----------
    key : str
        The key.

    Returns
    -------
    str

    Raises
    ------
    InputError
        ``key`` is not a string.

    Examples
    --------
    >>> toml_key("n_sensors"), toml_key("a b")
    ('n_sensors', '"a b"')
    """
    if not isinstance(key, str):
        raise InputError(f"A TOML key must be a string. Got {key!r:.60}.")
    return key if _BARE_KEY.fullmatch(key) else toml_string(key)


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


# Keys made redundant by another key of their section (written commented out in templates, and
# a conflict when a file sets both): key -> (the other keys, why).
