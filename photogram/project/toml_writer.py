"""A small TOML writer for the documents photogram writes (.prj, cameras).

Supports strings, booleans, integers, floats (written with ``repr`` so that
they read back exactly), arrays, inline tables (:class:`Inline`), tables and
arrays of tables, and comments above tables. ``None`` values are skipped
(TOML has no null).

User strings (a project name, a file name) in comments are written with
:func:`comment_string`, as a quoted TOML string with its control characters
escaped, so that a name with a line break or a bell character stays on its
comment line and the file reads back; :func:`dumps` itself escapes every
control character but tab that a comment line still holds (TOML forbids them
in comments).
"""

from __future__ import annotations

import math
import re
from typing import Any, Mapping

__all__ = ["Inline", "dumps", "format_value", "format_key", "comment_string",
           "comment_line"]

_BARE = re.compile(r"[A-Za-z0-9_-]+")
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n",
            "\f": "\\f", "\r": "\\r"}
# characters that end a line for str.splitlines (and some editors) beyond the
# C0 controls: escaped in comments too
_LINE_BREAKS = {"\x85", "\u2028", "\u2029"}


class Inline(dict):
    """A table written inline: ``{ value = 1.0, free = true }``."""


def format_key(key: str) -> str:
    """A bare key if possible, else a quoted one."""
    key = str(key)
    return key if _BARE.fullmatch(key) else _string(key)


def _string(text: str) -> str:
    return _quoted(str(text))


def _control(ch: str) -> bool:
    return ord(ch) < 0x20 or ord(ch) == 0x7F or ch in _LINE_BREAKS


def comment_string(text) -> str:
    """A user string for a comment line: as it is when it holds no control
    character, quote or backslash, else quoted with these escaped as in a
    TOML string (so a line break cannot end the comment)."""
    text = str(text)
    if not any(_control(ch) or ch in '"\\' for ch in text):
        return text
    return _quoted(text)


def _quoted(text: str) -> str:
    out = []
    for ch in text:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif _control(ch):
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def comment_line(text: str) -> str:
    """One comment line's text with every control character but tab escaped
    (``\\uXXXX``), so that it cannot end the comment or break the file."""
    return "".join(ch if ch == "\t" or not _control(ch) else f"\\u{ord(ch):04X}"
                   for ch in str(text))


def _comment_lines(text) -> list[str]:
    """``# ...`` lines of a comment; only ``\\n`` separates lines."""
    return [f"# {comment_line(t)}" if t else "#" for t in str(text or "").split("\n")]


def _float(value: float) -> str:
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return repr(value)


def format_value(value: Any) -> str:
    """TOML text of a scalar, array or inline table."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _float(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    if isinstance(value, Mapping):
        items = [f"{format_key(k)} = {format_value(v)}" for k, v in value.items()
                 if v is not None]
        return "{ " + ", ".join(items) + " }" if items else "{}"
    if hasattr(value, "item"):  # numpy scalar
        return format_value(value.item())
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def _is_table(value: Any) -> bool:
    return isinstance(value, Mapping) and not isinstance(value, Inline)


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(_is_table(v) for v in value)


def _emit(lines: list[str], path: tuple[str, ...], table: Mapping, comments: Mapping,
          *, array: bool = False) -> None:
    scalars = [(k, v) for k, v in table.items()
               if v is not None and not _is_table(v) and not _is_table_array(v)]
    children = [(k, v) for k, v in table.items() if _is_table(v) or _is_table_array(v)]
    if path and (scalars or array or not children):
        if lines:
            lines.append("")
        if comments.get(path):
            lines += _comment_lines(comments[path])
        name = ".".join(format_key(p) for p in path)
        lines.append(f"[[{name}]]" if array else f"[{name}]")
    for key, value in scalars:
        lines.append(f"{format_key(key)} = {format_value(value)}")
    for key, value in children:
        if _is_table_array(value):
            for entry in value:
                _emit(lines, path + (key,), entry, comments, array=True)
        else:
            _emit(lines, path + (key,), value, comments)


def dumps(doc: Mapping, *, header: str | None = None,
          comments: Mapping[tuple, str] | None = None) -> str:
    """TOML text of ``doc``.

    Parameters
    ----------
    doc : mapping
        Nested dicts; :class:`Inline` dicts are written inline, lists of dicts
        as arrays of tables.
    header : str, optional
        Comment lines at the top of the file.
    comments : mapping, optional
        Comment lines written above the table at a key path, e.g.
        ``{("cameras", "K1"): "taken from lab/results/cameras.toml"}``.
    """
    lines: list[str] = _comment_lines(header) if header else []
    _emit(lines, (), doc, comments or {})
    return "\n".join(lines) + "\n"
