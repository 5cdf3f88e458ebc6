"""The contact sheet of a tracking run: for a few exposures and every
station, the frame around the jumper with the labels (markers found:
green circle and name; flagged: red cross at the prediction when there is
one, with the status), the sampled ski-line points (yellow) and the
exposure id (docs/track.md)."""

from __future__ import annotations

import cv2
import numpy as np

from photogram.project.atomic import atomic_write_bytes

__all__ = ["contact_sheet", "crop_window"]

GREEN, RED, YELLOW, WHITE = (60, 200, 60), (40, 40, 230), (40, 220, 230), (255, 255, 255)


def crop_window(centre, size, shape):
    """Top-left corner (x, y) of a ``size`` (w, h) window around ``centre``
    clipped into an image of ``shape`` (h, w)."""
    w, h = size
    H, W = shape[:2]
    x0 = int(np.clip(round(centre[0] - w / 2), 0, max(W - w, 0)))
    y0 = int(np.clip(round(centre[1] - h / 2), 0, max(H - h, 0)))
    return x0, y0


def contact_sheet(result, path, *, n_columns: int = 6, size=(160, 120), zoom: int = 2):
    """Write the contact sheet PNG of ``result`` (a
    :class:`~photogram.track.pipeline.TrackResult`) to ``path``: columns
    are ``n_columns`` exposures spread over the jump, rows the stations;
    each cell a ``size`` crop around the markers found, enlarged ``zoom``
    times."""
    ids = list(result.exposures.ids)
    pick = sorted(set(np.linspace(0, len(ids) - 1, min(n_columns, len(ids))).round()
                      .astype(int).tolist()))
    stations = list(result.frames)
    w, h = size[0] * zoom, size[1] * zoom
    sheet = np.full((len(stations) * (h + 4) + 4, len(pick) * (w + 4) + 4, 3), 30, np.uint8)
    m = result.markers
    sk = result.skis
    for r, s in enumerate(stations):
        frames_s = result.exposures.in_station(result.offsets.get(s, 0))
        for c, e in enumerate(pick):
            eid = ids[e]
            img = result.frames[s][frames_s[e]]
            rows = m[(m.station == s) & (m.exposure == eid)]
            ok = rows[rows.status == "ok"]
            if len(ok):
                centre = ok[["x", "y"]].to_numpy().mean(0)
            else:
                centre = (img.shape[1] / 2, img.shape[0] / 2)
            x0, y0 = crop_window(centre, size, img.shape)
            crop = img[y0:y0 + size[1], x0:x0 + size[0]]
            cell = cv2.resize(cv2.cvtColor(crop, cv2.COLOR_GRAY2BGR), (w, h),
                              interpolation=cv2.INTER_NEAREST)
            pts = sk[(sk.station == s) & (sk.exposure == eid)]
            for x, y in pts[["x", "y"]].to_numpy():
                cv2.circle(cell, _cell_xy(x, y, x0, y0, zoom), 1, YELLOW, -1)
            for _, row in rows.iterrows():
                if row.status == "ok":
                    p = _cell_xy(row.x, row.y, x0, y0, zoom)
                    cv2.circle(cell, p, 6, GREEN, 1, cv2.LINE_AA)
                    cv2.putText(cell, str(row.marker), (p[0] + 7, p[1] - 4),
                                cv2.FONT_HERSHEY_SIMPLEX, 0.35, GREEN, 1, cv2.LINE_AA)
                else:
                    px, py = row.get("x_pred", np.nan), row.get("y_pred", np.nan)
                    if np.isfinite(px) and np.isfinite(py):
                        p = _cell_xy(px, py, x0, y0, zoom)
                        cv2.drawMarker(cell, p, RED, cv2.MARKER_TILTED_CROSS, 10, 1)
                        cv2.putText(cell, f"{row.marker} {row.status}", (p[0] + 7, p[1] + 10),
                                    cv2.FONT_HERSHEY_SIMPLEX, 0.35, RED, 1, cv2.LINE_AA)
            cv2.putText(cell, f"{s} exposure {eid}", (4, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                        WHITE, 1, cv2.LINE_AA)
            y, x = 4 + r * (h + 4), 4 + c * (w + 4)
            sheet[y:y + h, x:x + w] = cell
    ok, buf = cv2.imencode(".png", sheet)
    atomic_write_bytes(path, buf.tobytes())
    return sheet


def _cell_xy(x, y, x0, y0, zoom):
    """OpenCV pixel indices in a cell enlarged ``zoom`` times of image
    coordinates in the project's convention (top-left corner of the image at
    (0, 0), docs/measure.md) of a crop whose top-left pixel is (x0, y0)."""
    return int(round((x - x0) * zoom - 0.5)), int(round((y - y0) * zoom - 0.5))
