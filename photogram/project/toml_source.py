"""TOML with line numbers and typed, checked access to its keys.

TOML line numbers come from tomllib's syntax errors or, for semantic
errors, from a best-effort index of the lines where sections and keys are
written (:class:`TomlSource`); :class:`Section` reads one table's keys with
type and range checks, every problem becoming one
:class:`~photogram.errors.InputError` with file, line and hint.
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any, Iterable

from photogram.errors import InputError
from photogram.project.limits import MAX_NESTING, check_nesting
from photogram.project.text_input import DOCS, read_text, suggest

__all__ = ["TomlSource", "Section", "type_name", "MISSING"]

MISSING = object()

_LOCATION = re.compile(r"\s*\(at line (\d+), column \d+\)\s*$")
_AT_END = re.compile(r"\s*\(at end of document\)\s*$")
_KEY = r'(?:[A-Za-z0-9_-]+|"(?:[^"\\]|\\.)*"|\'[^\']*\')'
_KEY_PART = re.compile(r'\s*(' + _KEY + r')\s*(?:\.|$)')
_HEADER = re.compile(r'^\[(\[?)\s*(' + _KEY + r'(?:\s*\.\s*' + _KEY + r')*)\s*\]\]?\s*(#.*)?$')
_ASSIGN = re.compile(r'^(' + _KEY + r'(?:\s*\.\s*' + _KEY + r')*)\s*=')
_INLINE_KEY = re.compile(r'[{,]\s*([A-Za-z0-9_-]+)\s*=')


def _split_keys(text: str) -> tuple[str, ...] | None:
    """Split a dotted TOML key into its parts (quotes removed)."""
    parts, pos = [], 0
    while pos < len(text):
        m = _KEY_PART.match(text, pos)
        if not m:
            return None
        key = m.group(1)
        parts.append(key[1:-1] if key[0] in "\"'" else key)
        pos = m.end()
    return tuple(parts)


def _index_lines(text: str) -> dict[tuple, int]:
    """Map key paths to the 1-based line where they are written.

    Array-of-tables entries get their index as a path element:
    ``("constraints", "distance", 1)`` is the second ``[[constraints.distance]]``.
    """
    index: dict[tuple, int] = {}
    counts: dict[tuple, int] = {}
    current: tuple = ()
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        header = _HEADER.match(line)
        if header and (keys := _split_keys(header.group(2))):
            if header.group(1):
                i = counts.get(keys, 0)
                counts[keys] = i + 1
                index.setdefault(keys, number)
                keys = keys + (i,)
            current = keys
            index.setdefault(current, number)
            continue
        assign = _ASSIGN.match(line)
        if assign and (keys := _split_keys(assign.group(1))):
            for k in range(1, len(keys) + 1):
                index.setdefault(current + keys[:k], number)
            for inner in _INLINE_KEY.finditer(line, assign.end()):
                index.setdefault(current + keys + (inner.group(1),), number)
    return index


def _syntax_error(exc: tomllib.TOMLDecodeError, path: Path) -> InputError:
    msg = str(exc)
    line = None
    if m := _LOCATION.search(msg):
        line = int(m.group(1))
        msg = msg[:m.start()]
    elif m := _AT_END.search(msg):
        msg = msg[:m.start()] + " at the end of the file"
    if "Cannot declare" in msg or "Cannot overwrite" in msg:
        hint = "each section and each key may appear only once: is a camera or key written twice?"
    elif "Invalid value" in msg:
        hint = 'text needs double quotes, e.g. datum = "control"'
    else:
        hint = f"see {DOCS} for the syntax"
    return InputError(f"TOML syntax error: {msg}", file=path, line=line, hint=hint)


class TomlSource:
    """A parsed TOML file that can say on which line a key is written.

    Parameters
    ----------
    path : Path
        The file (as it should appear in messages).
    text : str
        Its text.
    data : dict
        The parsed document.
    """

    def __init__(self, path: Path, text: str, data: dict):
        self.path = Path(path)
        self.text = text
        self.data = data
        self._index: dict[tuple, int] | None = None    # built on first use

    @property
    def _lines(self) -> dict[tuple, int]:
        """Key path -> line (:func:`_index_lines`), indexed when first asked:
        most files read without an error never need it."""
        if self._index is None:
            self._index = _index_lines(self.text)
        return self._index

    @classmethod
    def load(cls, path: Path, what: str = "project file") -> "TomlSource":
        """Read and parse ``path``; syntax errors carry tomllib's line."""
        text = read_text(path, what)
        check_nesting(text, Path(path), "TOML")     # before tomllib recurses
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise _syntax_error(exc, Path(path)) from None
        except RecursionError:
            raise InputError("arrays or tables nested too deeply", file=path,
                             hint=f"photogram reads TOML nested at most {MAX_NESTING} levels; "
                                  "the file is damaged or not a photogram file") from None
        return cls(Path(path), text, data)

    def line_of(self, keypath: Iterable) -> int | None:
        """Line of ``keypath``, else of its closest written parent."""
        keypath = tuple(keypath)
        while keypath:
            if keypath in self._lines:
                return self._lines[keypath]
            keypath = keypath[:-1]
        return None

    def root(self) -> "Section":
        """The whole document as a :class:`Section`."""
        return Section(self, (), self.data, f"{self.path.name}")


def type_name(value: Any) -> str:
    """How a TOML value's type is called in messages."""
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a number"
    if isinstance(value, str):
        return f'a string ("{value}")'
    if isinstance(value, list):
        text = repr(value)
        return f"the array {text}" if len(text) <= 40 else "an array"
    if isinstance(value, dict):
        return "a table"
    return type(value).__name__


class Section:
    """One TOML table with typed, checked access to its keys.

    Parameters
    ----------
    source : TomlSource
        The file, for line numbers.
    keypath : tuple
        Path of this table in the document.
    data : dict
        The table's content.
    label : str
        How messages name it, e.g. ``[cameras.K1]``.
    """

    def __init__(self, source: TomlSource, keypath: tuple, data: dict, label: str):
        self.source, self.keypath, self.data, self.label = source, keypath, data, label

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def error(self, key: str | None, what: str, hint: str | None = None) -> InputError:
        """An InputError at the line of ``key`` (or of this section)."""
        path = self.keypath + ((key,) if key is not None else ())
        return InputError(what, file=self.source.path,
                          line=self.source.line_of(path), hint=hint)

    def check_keys(self, allowed: Iterable[str], required: Iterable[str] = (),
                   *, noun: str = "key") -> None:
        """Reject unknown keys (with a suggestion) and missing required ones."""
        allowed = list(allowed)
        for key in self.data:
            if key not in allowed:
                raise self.error(key, f"unknown {noun} '{key}' in {self.label}",
                                 hint=suggest(key, allowed))
        for key in required:
            if key not in self.data:
                raise self.error(None, f"{self.label} has no {key}",
                                 hint=f"add {key} = ...; see {DOCS}")

    def _get(self, key: str, default: Any) -> Any:
        if key in self.data:
            return self.data[key]
        if default is MISSING:
            raise self.error(None, f"{self.label} has no {key}",
                             hint=f"add {key} = ...; see {DOCS}")
        return default

    def _wrong_type(self, key: str, want: str, example: str) -> InputError:
        value = self.data[key]
        return self.error(key, f"{key} in {self.label} must be {want}, not {type_name(value)}",
                          hint=f"e.g. {key} = {example}")

    def table(self, key: str, *, required: bool = True) -> "Section | None":
        """The sub-table ``key`` (None if absent and not required)."""
        if key not in self.data:
            if required:
                raise self.error(None, f"missing section [{self._dotted(key)}]",
                                 hint=f"add a [{self._dotted(key)}] section; see {DOCS}")
            return None
        if not isinstance(self.data[key], dict):
            raise self.error(key, f"{self._dotted(key)} must be a section [{self._dotted(key)}], "
                                  f"not {type_name(self.data[key])}",
                             hint=f"write it as [{self._dotted(key)}] followed by its keys")
        return Section(self.source, self.keypath + (key,), self.data[key],
                       f"[{self._dotted(key)}]")

    def table_array(self, key: str) -> list["Section"]:
        """Entries of an array of tables ``[[key]]`` (a single table counts as one)."""
        value = self.data.get(key, [])
        if isinstance(value, dict):
            return [self.table(key)]
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self._wrong_type(key, "an array of tables", f"[[{self._dotted(key)}]]")
        name = self._dotted(key)
        return [Section(self.source, self.keypath + (key, i), v, f"[[{name}]] #{i + 1}")
                for i, v in enumerate(value)]

    def _dotted(self, key: str) -> str:
        parts = [str(k) for k in self.keypath if not isinstance(k, int)] + [key]
        return ".".join(parts)

    def string(self, key: str, default: Any = MISSING, *,
               choices: Iterable[str] | None = None) -> Any:
        """A string value, optionally one of ``choices``."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        if not isinstance(value, str):
            example = f'"{next(iter(choices))}"' if choices else '"text"'
            raise self._wrong_type(key, "a string", example)
        if choices is not None and value not in choices:
            raise self.error(key, f"unknown {key} '{value}' in {self.label}",
                             hint=suggest(value, choices, noun="use one of"))
        return value

    def ident(self, key: str, default: Any = MISSING) -> Any:
        """An id: a string, or an integer taken as its decimal text."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        if isinstance(value, bool) or not isinstance(value, (str, int)):
            raise self._wrong_type(key, "an id (text or integer)", '"P17"')
        value = str(value).strip()
        if not value:
            raise self.error(key, f"{key} in {self.label} is empty", hint="give an id")
        return value

    def number(self, key: str, default: Any = MISSING, *, positive: bool = False,
               nonnegative: bool = False, below: float | None = None) -> Any:
        """A finite number (integers are accepted)."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self._wrong_type(key, "a number", "1.5")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(key, f"{key} in {self.label} must be a finite number, not {value}",
                             hint="nan and inf are not allowed")
        if positive and value <= 0 or nonnegative and value < 0 or \
                below is not None and value >= below:
            want = "> 0" if positive else ">= 0" if nonnegative else ""
            want = " and ".join(w for w in (want, f"< {below}" if below is not None else "") if w)
            raise self.error(key, f"{key} in {self.label} must be {want}, not {value!r}",
                             hint=f"see {DOCS}")
        return value

    def integer(self, key: str, default: Any = MISSING, *, minimum: int | None = None) -> Any:
        """An integer, optionally at least ``minimum``."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._wrong_type(key, "an integer", "50")
        if minimum is not None and value < minimum:
            raise self.error(key, f"{key} in {self.label} must be at least {minimum}, not {value}",
                             hint=f"see {DOCS}")
        return value

    def boolean(self, key: str, default: Any = MISSING) -> Any:
        """true or false."""
        value = self._get(key, default)
        if key in self.data and not isinstance(value, bool):
            raise self._wrong_type(key, "true or false", "true")
        return value

    def ids(self, key: str, default: Any = MISSING) -> Any:
        """An array of ids (strings or integers), returned as strings."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        if not isinstance(value, list) or any(
                isinstance(v, bool) or not isinstance(v, (str, int)) for v in value):
            raise self._wrong_type(key, "an array of ids", '["P1", "P2"]')
        return [str(v).strip() for v in value]

    def numbers(self, key: str, length: int, default: Any = MISSING, *,
                integer: bool = False) -> Any:
        """An array of ``length`` positive numbers (integers if ``integer``)."""
        value = self._get(key, default)
        if key not in self.data:
            return value
        kinds = (int,) if integer else (int, float)
        example = "[1920, 1080]" if integer else "[0.0055, 0.0055]"
        if not isinstance(value, list) or len(value) != length or any(
                isinstance(v, bool) or not isinstance(v, kinds) for v in value):
            raise self._wrong_type(
                key, f"an array of {length} {'integers' if integer else 'numbers'}", example)
        if any(not math.isfinite(v) or v <= 0 for v in value):
            raise self.error(key, f"{key} in {self.label} must be positive, not {value}",
                             hint=f"e.g. {key} = {example}")
        return tuple(int(v) if integer else float(v) for v in value)
