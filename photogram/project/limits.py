"""Limits on what photogram reads, checked before anything big is allocated.

Hostile or damaged input must end as one :class:`~photogram.errors.InputError`
naming the file, never as a ``RecursionError`` or ``MemoryError`` deep inside
a parser (docs/reliability.md, "Issue 16, item 21"). The limits:

============================  ==========================================
:data:`MAX_NESTING`           100 levels of arrays/tables (TOML) or
                              arrays/objects (JSON)
:data:`MAX_JSON_BYTES`        64 MiB for a summary.json
:data:`MAX_IMAGE_PIXELS`      250 megapixels per image or video frame
                              (width x height from the file's header)
:data:`MAX_DECOMPRESSED_BYTES`  256 MiB of text from a .bz2/.gz file (BAL),
                              measured while streaming
============================  ==========================================

A CSV cell may hold at most ``csv.field_size_limit()`` (131072) characters;
:mod:`photogram.project.tables` turns the csv module's error into an
InputError at the record's line.
"""

from __future__ import annotations

import bz2
import errno
import gzip
import json
import os
import re
import struct
from pathlib import Path

from photogram.errors import InputError
from photogram.project.text_input import decode_utf8

__all__ = ["MAX_NESTING", "MAX_JSON_BYTES", "MAX_IMAGE_PIXELS", "MAX_DECOMPRESSED_BYTES",
           "check_nesting", "read_json", "image_size", "check_image", "check_frame_size",
           "read_maybe_compressed", "check_output_path", "MIB"]

MIB = 1 << 20
MAX_NESTING = 100
MAX_JSON_BYTES = 64 * MIB
MAX_IMAGE_PIXELS = 250_000_000
MAX_DECOMPRESSED_BYTES = 256 * MIB

# strings and comments, whose brackets do not nest, or a bracket; an
# unterminated string runs to the end of its line (TOML) or of the text (JSON),
# so that every string pattern always matches and the scan stays linear
_TOML_TOKENS = re.compile(r'"""[\s\S]*?(?:"""|\Z)|\'\'\'[\s\S]*?(?:\'\'\'|\Z)'
                          r'|"(?:[^"\\\n]|\\[^\n])*+(?:"|[^\n]*)|\'[^\'\n]*\'?'
                          r'|#[^\n]*|[\[\]{}]')
_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\[\s\S])*+(?:"|[\s\S]*)|[\[\]{}]')


def check_nesting(text: str, path, kind: str = "TOML") -> None:
    """Refuse ``text`` if its arrays/tables nest deeper than :data:`MAX_NESTING`.

    Brackets inside strings (and TOML comments) do not count.

    Raises
    ------
    InputError
        At the line where the nesting passes the limit.
    """
    if text.count("[") + text.count("{") <= MAX_NESTING:
        return                          # cannot nest deeper (the usual case: no scan)
    depth = 0
    for m in (_TOML_TOKENS if kind == "TOML" else _JSON_TOKENS).finditer(text):
        token = m.group()
        if len(token) != 1 or token not in "[]{}":
            continue                    # a string or a comment
        depth += 1 if token in "[{" else -1
        if depth > MAX_NESTING:
            line = text.count("\n", 0, m.start()) + 1
            raise InputError(f"arrays or tables nested more than {MAX_NESTING} levels deep",
                             file=path, line=line,
                             hint=f"photogram reads {kind} nested at most {MAX_NESTING} levels; "
                                  "the file is damaged or not a photogram file")


def read_json(path, what: str = "file") -> dict:
    """Read a JSON object (a results folder's summary.json) within the limits.

    Raises
    ------
    InputError
        Missing, unreadable, larger than :data:`MAX_JSON_BYTES`, not UTF-8,
        nested deeper than :data:`MAX_NESTING`, not valid JSON, or not an
        object.
    """
    path = Path(path)
    damaged = "the file is damaged: run the command again"
    try:
        size = path.stat().st_size
        if size > MAX_JSON_BYTES:
            raise InputError(f"{what} is {size / MIB:.0f} MiB, more than photogram reads "
                             f"({MAX_JSON_BYTES // MIB} MiB)", file=path, hint=damaged)
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", file=path,
                         hint="check the file permissions") from None
    text = decode_utf8(data, path)
    check_nesting(text, path, "JSON")
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", file=path, line=exc.lineno,
                         hint=damaged) from None
    except (ValueError, RecursionError) as exc:       # e.g. an integer of 5000 digits
        reason = " ".join(str(exc).split(";")[0].split())[:120]
        raise InputError(f"not valid JSON: {reason}", file=path, hint=damaged) from None
    if not isinstance(value, dict):
        kind = "null" if value is None else "true/false" if isinstance(value, bool) else \
            "a number" if isinstance(value, (int, float)) else \
            "a string" if isinstance(value, str) else "an array"
        raise InputError(f"{what} holds {kind}, not a JSON object", file=path, hint=damaged)
    return value


# --------------------------------------------------------------------------
# images
# --------------------------------------------------------------------------

def _jpeg_size(f) -> tuple[int, int] | None:
    f.seek(2)
    while True:
        byte = f.read(1)
        while byte == b"\xff":
            byte = f.read(1)
        if not byte:
            return None
        marker = byte[0]
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            continue
        head = f.read(2)
        if len(head) < 2:
            return None
        length = struct.unpack(">H", head)[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            sof = f.read(5)
            if len(sof) < 5:
                return None
            h, w = struct.unpack(">HH", sof[1:5])
            return w, h
        if length < 2:
            return None
        f.seek(length - 2, os.SEEK_CUR)


def _tiff_size(f, head: bytes) -> tuple[int, int] | None:
    end = "<" if head[:2] == b"II" else ">"
    f.seek(struct.unpack(end + "I", head[4:8])[0])
    raw = f.read(2)
    if len(raw) < 2:
        return None
    size = {}
    for _ in range(min(struct.unpack(end + "H", raw)[0], 4096)):
        entry = f.read(12)
        if len(entry) < 12:
            break
        tag, kind = struct.unpack(end + "HH", entry[:4])
        if tag in (256, 257):
            size[tag] = struct.unpack(end + ("H" if kind == 3 else "I"),
                                      entry[8:10] if kind == 3 else entry[8:12])[0]
    return (size[256], size[257]) if len(size) == 2 else None


def _pnm_size(head: bytes) -> tuple[int, int] | None:
    text = re.sub(rb"#[^\n]*", b" ", head[2:]).split()
    try:
        return int(text[0]), int(text[1])
    except (IndexError, ValueError):
        return None


def image_size(path) -> tuple[int, int] | None:
    """(width, height) from the header of a PNG, JPEG, BMP, TIFF or PNM file,
    without decoding it; None for another or an unreadable header."""
    try:
        with open(path, "rb") as f:
            head = f.read(64)
            if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
                return struct.unpack(">II", head[16:24])
            if head[:2] == b"\xff\xd8":
                return _jpeg_size(f)
            if head[:2] == b"BM" and len(head) >= 26:
                w, h = struct.unpack("<ii", head[18:26])
                return abs(w), abs(h)
            if head[:4] in (b"II*\x00", b"MM\x00*"):
                return _tiff_size(f, head)
            if head[:1] == b"P" and head[1:2] in b"123456" and len(head) > 2:
                return _pnm_size(head)
    except (OSError, struct.error):
        return None
    return None


def check_frame_size(width: float, height: float, path, what: str = "image") -> None:
    """Refuse a frame of more than :data:`MAX_IMAGE_PIXELS` pixels."""
    if width * height > MAX_IMAGE_PIXELS:
        raise InputError(f"the {what} is {int(width)} x {int(height)} pixels, more than "
                         f"photogram reads ({MAX_IMAGE_PIXELS // 1_000_000} megapixels)",
                         file=path, hint="scale it down, or check that the file is not damaged")


def check_image(path) -> None:
    """Refuse an image whose header claims more than :data:`MAX_IMAGE_PIXELS`
    pixels, before it is decoded."""
    size = image_size(path)
    if size is not None:
        check_frame_size(size[0], size[1], path)


# --------------------------------------------------------------------------
# compressed text, output folders
# --------------------------------------------------------------------------

def read_maybe_compressed(path, limit: int | None = None, what: str = "file") -> bytes:
    """The bytes of a plain, .bz2 or .gz file (by content), at most ``limit``
    (default :data:`MAX_DECOMPRESSED_BYTES`) after decompression.

    A compressed file is first decompressed as a stream without keeping the
    output, to measure it; only a file within the limit is then read.

    Raises
    ------
    InputError
        Larger than the limit, unreadable or damaged.
    """
    path = Path(path)
    limit = MAX_DECOMPRESSED_BYTES if limit is None else int(limit)
    too_big = f"more than photogram reads ({limit / MIB:g} MiB)"
    try:
        with open(path, "rb") as f:
            magic = f.read(3)
        opener = bz2.open if magic == b"BZh" else gzip.open if magic[:2] == b"\x1f\x8b" else None
        if opener is None:
            size = path.stat().st_size
            if size > limit:
                raise InputError(f"the {what} is {size / MIB:.0f} MiB, {too_big}", file=path,
                                 hint="split the problem or use a smaller one")
            return path.read_bytes()
        total = 0
        with opener(path, "rb") as stream:
            while chunk := stream.read(min(limit + 1 - total, MIB)):
                total += len(chunk)
                if total > limit:
                    raise InputError(f"the {what} inflates to {too_big}", file=path,
                                     hint="a damaged or hostile archive, or a problem too big "
                                          "for photogram: split it or use a smaller one")
        with opener(path, "rb") as stream:
            return stream.read(limit + 1)
    except (OSError, EOFError, ValueError) as exc:
        raise InputError(f"cannot read the {what}: {exc}", file=path,
                         hint="the file is damaged or not compressed with bz2/gzip") from None


def check_output_path(path, option: str = "--output") -> None:
    """Refuse an output path that cannot be a folder: a symbolic-link loop, a
    file, or a path through a file.

    Raises
    ------
    InputError
        Naming the path and the option it came from.
    """
    path = Path(path)
    try:
        os.stat(path)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"{option}: a loop of symbolic links, not a folder", file=path,
                             hint="give a real folder; check the links with ls -l") from None
        if exc.errno == errno.ENOTDIR:
            raise InputError(f"{option}: a part of this path is a file, not a folder",
                             file=path, hint="give a folder path") from None
        if exc.errno == errno.ENAMETOOLONG:
            raise InputError(f"{option}: the path is too long", file=path,
                             hint="give a shorter folder path") from None
        return              # absent (created later) or not accessible (reported later)
    if not path.is_dir():
        raise InputError(f"{option}: a file, not a folder", file=path,
                         hint="give a folder path (it is created if needed)")
