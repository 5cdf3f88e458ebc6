"""PDF file structure: numbered objects, pages, fonts, images, the
cross-reference table and trailer (PDF 1.4).

The output depends only on what is drawn (no dates, no ids): the same pages
give the same bytes. Streams are Flate-compressed with zlib at a fixed level
(:data:`FLATE_LEVEL`).
"""

from __future__ import annotations

import zlib

import numpy as np

__all__ = ["PdfFile", "FONTS", "pdf_string", "FLATE_LEVEL"]

#: zlib level of every stream: 1 (issue 23, round 6) compresses the report's
#: page content and images 1.8-2.4 times faster than level 3 and makes the
#: file 7-9 % larger (CAMCAL's report 117 -> 126 kB, that of a simulated
#: 181,000-observation network 1.19 -> 1.31 MB); the content itself is the
#: same at any level (tested)
FLATE_LEVEL = 1

#: resource name -> base font (the PDF standard fonts; nothing embedded)
FONTS = {"F1": "Helvetica", "F2": "Helvetica-Bold", "F3": "Courier", "F4": "Courier-Bold"}


def pdf_string(text: str) -> bytes:
    """A PDF literal string of ``text`` in cp1252 (WinAnsiEncoding);
    raises UnicodeEncodeError for characters outside it."""
    raw = text.encode("cp1252")
    raw = raw.replace(b"\\", b"\\\\").replace(b"(", b"\\(").replace(b")", b"\\)")
    raw = raw.replace(b"\r", b"\\r").replace(b"\n", b"\\n")
    return b"(" + raw + b")"


def _info_string(text: str) -> bytes:
    try:
        return pdf_string(text)
    except UnicodeEncodeError:                 # document info: UTF-16BE with BOM
        raw = b"\xfe\xff" + text.encode("utf-16-be")
        return b"<" + raw.hex().encode() + b">"


class PdfFile:
    """A PDF being assembled in memory.

    Parameters
    ----------
    info : dict
        Document information (Title, Subject, Creator...); ``None`` values are
        left out.
    """

    def __init__(self, info: dict | None = None):
        self._objects: list[bytes | None] = [None, None]      # 1 catalog, 2 page tree
        self._pages: list[int] = []
        self._info = {k: v for k, v in (info or {}).items() if v is not None}
        self._fonts = {name: self._add(b"<< /Type /Font /Subtype /Type1 /BaseFont /"
                                       + base.encode() + b" /Encoding /WinAnsiEncoding >>")
                       for name, base in FONTS.items()}
        self._alphas: dict[str, int] = {}

    # ------------------------------------------------------------- objects
    def _add(self, body: bytes) -> int:
        self._objects.append(body)
        return len(self._objects)

    def _stream(self, head: bytes, data: bytes) -> int:
        packed = zlib.compress(data, FLATE_LEVEL)
        return self._add(b"<< " + head + b" /Filter /FlateDecode /Length "
                         + str(len(packed)).encode() + b" >>\nstream\n" + packed
                         + b"\nendstream")

    def alpha_state(self, alpha: float) -> str:
        """Resource name of a graphics state with fill and stroke opacity
        ``alpha`` (created once per value)."""
        key = f"{alpha:.3f}"
        if key not in self._alphas:
            self._alphas[key] = self._add(f"<< /Type /ExtGState /ca {key} /CA {key} >>".encode())
        return "GA" + key.replace(".", "_")

    def image(self, rgb, alpha=None, interpolate: bool = False) -> int:
        """An image XObject from ``rgb`` (h, w, 3) uint8, row 0 at the top,
        with an optional soft mask ``alpha`` (h, w) uint8; returns its
        object number (see :meth:`add_page`'s ``images``)."""
        rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
        h, w = rgb.shape[:2]
        head = (f"/Type /XObject /Subtype /Image /Width {w} /Height {h} "
                f"/BitsPerComponent 8 /Interpolate {'true' if interpolate else 'false'} ")
        smask = b""
        if alpha is not None:
            m = self._stream((head + "/ColorSpace /DeviceGray").encode(),
                             np.ascontiguousarray(alpha, dtype=np.uint8).tobytes())
            smask = f" /SMask {m} 0 R".encode()
        return self._stream((head + "/ColorSpace /DeviceRGB").encode() + smask, rgb.tobytes())

    def add_page(self, width: float, height: float, content: bytes,
                 images: dict | None = None) -> None:
        """A page of ``width`` x ``height`` points drawn by ``content``
        (operators of a content stream); ``images`` maps resource names
        used there to image object numbers."""
        fonts = b" ".join(f"/{n} {i} 0 R".encode() for n, i in self._fonts.items())
        xobj = b" ".join(f"/{n} {i} 0 R".encode() for n, i in (images or {}).items())
        gs = b" ".join(f"/GA{k.replace('.', '_')} {i} 0 R".encode()
                       for k, i in self._alphas.items())
        contents = self._stream(b"", content)
        res = b"<< /Font << " + fonts + b" >>"
        if xobj:
            res += b" /XObject << " + xobj + b" >>"
        if gs:
            res += b" /ExtGState << " + gs + b" >>"
        res += b" >>"
        self._pages.append(self._add(
            b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 " + _num(width) + b" "
            + _num(height) + b"] /Contents " + str(contents).encode() + b" 0 R /Resources "
            + res + b" >>"))

    # ---------------------------------------------------------------- output
    def tobytes(self) -> bytes:
        """The whole file: header, objects, xref table, trailer."""
        self._objects[0] = b"<< /Type /Catalog /Pages 2 0 R >>"
        kids = b" ".join(f"{p} 0 R".encode() for p in self._pages)
        self._objects[1] = (b"<< /Type /Pages /Kids [" + kids + b"] /Count "
                            + str(len(self._pages)).encode() + b" >>")
        info = self._add(b"<< " + b" ".join(b"/" + k.encode() + b" " + _info_string(str(v))
                                            for k, v in self._info.items()) + b" >>")
        out = [b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n"]
        pos, offsets = len(out[0]), []
        for i, body in enumerate(self._objects, 1):
            chunk = f"{i} 0 obj\n".encode() + body + b"\nendobj\n"
            offsets.append(pos)
            out.append(chunk)
            pos += len(chunk)
        n = len(self._objects) + 1
        xref = [f"xref\n0 {n}\n0000000000 65535 f \n".encode()]
        xref += [f"{o:010d} 00000 n \n".encode() for o in offsets]
        out += xref
        out.append(f"trailer\n<< /Size {n} /Root 1 0 R /Info {info} 0 R >>\nstartxref\n"
                   f"{pos}\n%%EOF\n".encode())
        self._objects.pop()                   # the info object: tobytes() can run again
        return b"".join(out)


def _num(x: float) -> bytes:
    return (f"{x:.2f}".rstrip("0").rstrip(".") or "0").encode()
