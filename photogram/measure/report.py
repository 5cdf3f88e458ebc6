"""The measurement report: each image drawn with its detections, and report.pdf.

:func:`draw_image` draws on a downsampled copy of an image (longest side
``width`` px): numbered targets (green ring and id), coded targets (blue,
code id), guided measurements (cyan), accepted but unnumbered targets
(orange), rejected code rings (magenta) and every rejected blob but the
specks rejected for size (red cross with the first letter of the reason: b border, h shape, r
roundness, e edge, f fit, c contrast).

:func:`report_pdf` writes ``report.pdf`` with matplotlib: a summary page
(counts per image: accepted, numbered, codes, rejections by reason; and
the targets seen in fewest images) and one page per image with its
drawing. Both are returned as bytes so that the command writes them
atomically.
"""

from __future__ import annotations

import io

import numpy as np

__all__ = ["draw_image", "png_bytes", "report_pdf"]

_COLOURS = {"numbered": (60, 180, 60), "code": (220, 90, 30), "guided": (220, 200, 40),
            "unnumbered": (0, 140, 255), "code_rejected": (200, 40, 200),
            "rejected": (40, 40, 230)}


def draw_image(gray: np.ndarray, result, width: int = 1200) -> np.ndarray:
    """BGR drawing of one image's measurement (module doc)."""
    import cv2
    h, w = gray.shape[:2]
    s = min(1.0, width / max(w, h))
    small = cv2.resize(gray, (int(round(w * s)), int(round(h * s))), interpolation=cv2.INTER_AREA)
    img = cv2.cvtColor(small, cv2.COLOR_GRAY2BGR) if small.ndim == 2 else small.copy()
    det = result.detections
    lab = result.numbering.labels
    guided = det.extra.get("guided", np.zeros(len(det), bool))
    fs = max(0.3, 0.35 * width / 1200)
    for i in range(len(det)):
        x, y = det.xy[i] * s
        r = max(3, int(round(det.axes[i, 0] * s)) + 2)
        code = result.code_label[i]
        if code is None:
            kind = "code_rejected"
        elif code:
            kind = "code"
        elif guided[i]:
            kind = "guided"
        elif lab[i]:
            kind = "numbered"
        else:
            kind = "unnumbered"
        col = _COLOURS[kind]
        cv2.circle(img, (int(round(x)), int(round(y))), r, col, 1, cv2.LINE_AA)
        if lab[i]:
            cv2.putText(img, str(lab[i]), (int(x + r), int(y - r)), cv2.FONT_HERSHEY_SIMPLEX,
                        fs, col, 1, cv2.LINE_AA)
    for (x, y), why in zip(det.rejected_xy * s, det.rejected_reason):
        if why == "size":             # specks: counted, not drawn (they would hide the image)
            continue
        p = (int(round(x)), int(round(y)))
        cv2.drawMarker(img, p, _COLOURS["rejected"], cv2.MARKER_TILTED_CROSS, 6, 1)
        cv2.putText(img, {"shape": "h"}.get(why, why[:1]), (p[0] + 3, p[1] - 3),
                    cv2.FONT_HERSHEY_SIMPLEX, fs * 0.8, _COLOURS["rejected"], 1, cv2.LINE_AA)
    return img


def png_bytes(image: np.ndarray) -> bytes:
    """PNG encoding of an image."""
    import cv2
    ok, buf = cv2.imencode(".png", image)
    if not ok:  # pragma: no cover - encoding a valid array does not fail
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def report_pdf(measurement, drawings: dict) -> bytes:
    """report.pdf of a measurement: summary page + one page per image."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    buf = io.BytesIO()
    keys = ("accepted", "numbered", "codes", "code_rejected", "unnumbered", "size", "border",
            "shape", "roundness", "edge", "fit", "contrast")
    with PdfPages(buf, metadata={"Creator": "photogram measure", "CreationDate": None}) as pdf:
        fig = plt.figure(figsize=(8.27, 11.69))
        fig.text(0.06, 0.96, f"photogram measure: {measurement.field.name}", fontsize=13,
                 weight="bold")
        rows = [[im.name] + [str(im.counts()[k]) for k in keys] for im in measurement.images]
        total = [sum(int(r[i + 1]) for r in rows) for i in range(len(keys))]
        rows.append(["total"] + [str(t) for t in total])
        ax = fig.add_axes([0.04, 0.25, 0.92, 0.68])
        ax.axis("off")
        tab = ax.table(cellText=rows, colLabels=["image"] + [k.replace("_", " ") for k in keys],
                       loc="upper center", cellLoc="right")
        tab.auto_set_font_size(False)
        tab.set_fontsize(6)
        tab.scale(1, 1.1)
        per_target: dict[str, int] = {}
        for _, pt, *_ in measurement.table():
            per_target[pt] = per_target.get(pt, 0) + 1
        few = sorted(per_target.items(), key=lambda kv: (kv[1], kv[0]))[:12]
        fig.text(0.06, 0.2, f"{len(measurement.table())} observations of {len(per_target)} "
                 f"targets in {len(measurement.images)} images. Fewest images: "
                 + ", ".join(f"{k} ({v})" for k, v in few), fontsize=8, wrap=True)
        problems = measurement.problems()
        fig.text(0.06, 0.12, "Problems: " + ("; ".join(problems[:8]) if problems else "none"),
                 fontsize=8, wrap=True)
        fig.text(0.06, 0.06, "Rejections: size (diameter range), border (touches the image "
                 "border), shape (fill ratio of the moment ellipse), roundness, edge (too few "
                 "edge points), fit (ellipse residual), contrast; code rejected: a ring that "
                 "decodes to no code.", fontsize=7, wrap=True)
        pdf.savefig(fig)
        plt.close(fig)
        for im in measurement.images:
            d = drawings.get(im.name)
            if d is None:
                continue
            fig = plt.figure(figsize=(11.69, 8.27))
            ax = fig.add_axes([0.02, 0.06, 0.96, 0.88])
            ax.imshow(d[:, :, ::-1])
            ax.axis("off")
            c = im.counts()
            fig.text(0.02, 0.96, f"{im.name}: {c['numbered']} numbered, {c['codes']} codes, "
                     f"{c['unnumbered']} unnumbered, {c['code_rejected']} code rings rejected, "
                     f"{sum(c[k] for k in keys[5:])} blobs rejected", fontsize=10)
            fig.text(0.02, 0.02, "green numbered, blue code, cyan guided, orange unnumbered, "
                     "magenta rejected ring, red x rejected blob (b border, h shape, "
                     "r roundness, e edge, f fit, c contrast)", fontsize=8)
            pdf.savefig(fig)
            plt.close(fig)
    return buf.getvalue()
