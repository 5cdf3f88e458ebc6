"""An orthographic 3D view for the report's network page: a cube of equal
scales around the data, seen as matplotlib's default view (azimuth -60 deg,
elevation 30 deg), with grey back panes, grid lines at nice ticks, axis
labels, markers, lines and text drawn far to near per layer."""

from __future__ import annotations

import numpy as np

from photogram.report.pdf.guides import draw_legend
from photogram.report.pdf.canvas import text_width
from photogram.report.pdf.ticks import nice_ticks, tick_labels

__all__ = ["Axes3D", "view_basis"]


def view_basis(azim: float = -60.0, elev: float = 30.0):
    """Unit vectors (screen x, screen y, towards the viewer) in world
    coordinates for a view from ``azim``/``elev`` degrees."""
    a, e = np.radians(azim), np.radians(elev)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    sx = np.array([-np.sin(a), np.cos(a), 0.0])
    sy = np.cross(eye, sx)
    return sx, sy, eye


class Axes3D:
    """3D axes in the page box ``rect`` (points) of ``canvas``."""

    native = True

    def __init__(self, canvas, rect):
        self.canvas, self.rect = canvas, tuple(float(v) for v in rect)
        self.layers: list = []
        self.labels = ("X", "Y", "Z")
        self.lo = np.zeros(3)
        self.half = 1.0
        self.tick_size = 6.0
        self.handles: list = []
        self.legend_spec = None

    def set_box(self, xyz) -> None:
        """An equal-scale cube around the points ``xyz`` (n, 3)."""
        lo, hi = np.nanmin(xyz, axis=0), np.nanmax(xyz, axis=0)
        self.mid = (lo + hi) / 2
        self.half = max(float((hi - lo).max()) / 2, 1e-9)

    def set_labels(self, x, y, z) -> None:
        self.labels = (x, y, z)

    def scatter(self, xyz, marker="o", color="black", s=9.0, label=None) -> None:
        self.layers.append(("markers", np.asarray(xyz, float).reshape(-1, 3), marker, color,
                            float(np.sqrt(s))))
        if label:
            self.handles.append((label, dict(color=color, marker=marker, ms=np.sqrt(s),
                                             ls=None, lw=1.0)))

    def segments(self, a, b, color="black", lw=0.8) -> None:
        self.layers.append(("segments", np.asarray(a, float).reshape(-1, 3),
                            np.asarray(b, float).reshape(-1, 3), color, lw))

    def text(self, xyz, s, size=6.5) -> None:
        self.layers.append(("text", np.asarray(xyz, float).reshape(3), s, size))

    def legend(self, loc="upper left", fontsize=7, **_):
        self.legend_spec = (loc, None, fontsize, True)

    # ---------------------------------------------------------------- draw
    def _projector(self):
        sx, sy, _ = view_basis()
        corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        P = corners @ np.stack([sx, sy], 1)
        x0, y0, w, h = self.rect
        span = P.max(axis=0) - P.min(axis=0)
        scale = min(w / span[0], h / span[1]) * 0.8
        centre = np.array([x0 + w / 2, y0 + h / 2]) - scale * (P.max(axis=0) + P.min(axis=0)) / 2
        B = np.stack([sx, sy], 1) * scale / self.half

        def project(xyz):
            return (np.asarray(xyz, float).reshape(-1, 3) - self.mid) @ B + centre
        return project

    def render(self) -> None:
        c = self.canvas
        project = self._projector()
        lo, hi = self.mid - self.half, self.mid + self.half
        # back panes x = lo, y = hi, z = lo (away from the viewer)
        panes = [np.array([[lo[0], a, b] for a, b in ((lo[1], lo[2]), (hi[1], lo[2]),
                                                      (hi[1], hi[2]), (lo[1], hi[2]))]),
                 np.array([[a, hi[1], b] for a, b in ((lo[0], lo[2]), (hi[0], lo[2]),
                                                      (hi[0], hi[2]), (lo[0], hi[2]))]),
                 np.array([[a, b, lo[2]] for a, b in ((lo[0], lo[1]), (hi[0], lo[1]),
                                                      (hi[0], hi[1]), (lo[0], hi[1]))])]
        c.fill_style("0.95")
        c.stroke_style("0.6", 0.5)
        for pane in panes:
            c.polyline(project(pane), close=True, fill=True, stroke=True)
        ticks = [nice_ticks(lo[i], hi[i], 4) for i in range(3)]
        self._grid(project, ticks, lo, hi)
        self._axes(project, ticks, lo, hi)
        for layer in self.layers:
            kind = layer[0]
            if kind == "markers":
                _, xyz, marker, color, size = layer
                c.fill_style(color)
                c.stroke_style(color, 0.5)
                c.markers(project(xyz), marker, size)
            elif kind == "segments":
                _, a, b, color, lw = layer
                c.stroke_style(color, lw)
                c.segments(project(a), project(b))
            else:
                _, xyz, s, size = layer
                p = project(xyz)[0]
                c.text(p[0], p[1], f" {s}", size)
        if self.legend_spec and self.handles:
            from types import SimpleNamespace
            box = SimpleNamespace(box=self.rect)
            draw_legend(self, box, *self.legend_spec)

    def _grid(self, project, ticks, lo, hi):
        """Grid lines on the back panes at the ticks."""
        a, b = [], []
        for t in ticks[0]:               # x ticks on the y = hi and z = lo panes
            a += [[t, hi[1], lo[2]], [t, lo[1], lo[2]]]
            b += [[t, hi[1], hi[2]], [t, hi[1], lo[2]]]
        for t in ticks[1]:               # y ticks on the x = lo and z = lo panes
            a += [[lo[0], t, lo[2]], [lo[0], t, lo[2]]]
            b += [[lo[0], t, hi[2]], [hi[0], t, lo[2]]]
        for t in ticks[2]:               # z ticks on the x = lo and y = hi panes
            a += [[lo[0], lo[1], t], [lo[0], hi[1], t]]
            b += [[lo[0], hi[1], t], [hi[0], hi[1], t]]
        if a:
            self.canvas.stroke_style("0.8", 0.4)
            self.canvas.segments(project(a), project(b))

    def _axes(self, project, ticks, lo, hi):
        """Tick labels and axis labels along three front edges."""
        c = self.canvas
        centre = project([self.mid])[0]
        edges = [lambda t: [t, lo[1], lo[2]], lambda t: [hi[0], t, lo[2]],
                 lambda t: [lo[0], lo[1], t]]
        for i in range(3):
            pts = project([edges[i](t) for t in ticks[i]]) if len(ticks[i]) else np.zeros((0, 2))
            mid = project([edges[i](self.mid[i])])[0]
            out = mid - centre
            out = out / (np.hypot(*out) or 1.0)
            if i == 2:
                out = np.array([-1.0, 0.0])
            labels = tick_labels(ticks[i])
            for p, lab in zip(pts, labels):
                q = p + 10 * out
                c.text(q[0], q[1] - 2, lab, self.tick_size, ha="center")
            # beyond the tick labels: half the widest one across, plus a gap
            widest = max([text_width(lab, self.tick_size) for lab in labels] or [0.0])
            reach = 10 + 0.5 * widest * abs(out[0]) + 0.5 * self.tick_size * abs(out[1])
            own = 0.5 * text_width(self.labels[i], 8) * abs(out[0]) + 4 * abs(out[1])
            q = mid + (reach + 6 + own) * out
            c.text(q[0], q[1] - 3, self.labels[i], 8, ha="center")
