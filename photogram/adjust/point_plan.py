"""The plan of the fused point-ordered BAL path
(:mod:`photogram.adjust.point_rows`): the E-rows point by point, fixed
per structure, and the work arrays that the path reuses between
iterations (fresh arrays of this size are new pages that the kernel must
zero: at 10^7 observations seconds of system time per solve).
"""

from __future__ import annotations

import weakref

import numpy as np

__all__ = ["Plan"]


class Plan:
    """Row indices of the fused path (fixed per structure): the E-rows
    point by point, the points ordered by the first row group (camera)
    that sees them, so that consecutive points share cameras and the
    per-camera sums stay in cache (the order does not change any sum of
    a point; the per-camera sums are taken in another order)."""

    def __init__(self, block, st):
        cls = st.e_classes[0]
        ptr0 = st.pt_ptr
        cnt = np.diff(ptr0)
        grp0 = st.e_group[st.pt_rows]
        first = np.full(len(cnt), np.iinfo(np.int64).max)
        seen = cnt > 0
        if seen.any():
            first[seen] = np.minimum.reduceat(grp0, ptr0[:-1][seen])
        order = np.argsort(first, kind="stable")
        cnt = cnt[order]
        ptr = np.concatenate([[0], np.cumsum(cnt)]).astype(np.int64)
        idx = np.repeat(ptr0[order] - ptr[:-1], cnt) + np.arange(ptr[-1])
        self.erows = st.pt_rows[idx]                        # E-row of each processed row
        self.point = order.astype(np.int64)                 # point of each segment
        self.ptr = ptr
        rows = cls.rows[self.erows]                         # block row of each processed row
        self.block = block
        self.rows = rows
        self.station = np.ascontiguousarray(block.station[rows], dtype=np.int64)
        self.camera = np.ascontiguousarray(block.camera[rows], dtype=np.int64)
        self.group = np.ascontiguousarray(st.e_group[self.erows], dtype=np.int64)
        self.gcols = np.ascontiguousarray(st.group_cols, dtype=np.int64)
        seg = np.repeat(np.arange(len(cnt)), cnt)
        # at most one row per (point, group): the Schur-Jacobi pass needs no merging
        self.unique = not np.any((seg[1:] == seg[:-1]) & (self.group[1:] == self.group[:-1]))
        self._xy = (None, None)
        self.buffers = []                                   # [(arrays, weakref to owner)]
        self._scratch = {}

    def row_points(self):
        """The point of every processed row."""
        return np.repeat(self.point, np.diff(self.ptr))

    def xy(self):
        """The block's observations in point order (copied again when the
        block's array is replaced, e.g. by ``set_observations``)."""
        src, copy = self._xy
        if src is not self.block.xy:
            copy = np.ascontiguousarray(self.block.xy[self.rows])
            self._xy = (self.block.xy, copy)
        return copy

    def buffers_for(self, shapes):
        """Float arrays of ``shapes`` that no live :class:`PointSystem`
        uses (reused between iterations: fresh memory costs page faults
        as much as the kernel's work): ``(k, arrays)``; ``own(k, system)``
        marks them used."""
        for k, (arrs, owner) in enumerate(self.buffers):
            if owner() is None and [a.shape for a in arrs] == list(shapes):
                self.buffers[k] = (arrs, _taken)
                return k, arrs
        self.buffers.append(([np.empty(sh) for sh in shapes], _taken))
        return len(self.buffers) - 1, self.buffers[-1][0]

    def own(self, k, system):
        self.buffers[k] = (self.buffers[k][0], weakref.ref(system))

    def scratch(self, name, shape):
        """A float work array ``name`` of ``shape``, reused by every call
        (for temporaries that do not outlive the call that asks: the
        gathered points of a cost or a linearization, the damped ``A^-1``
        and the back-substitution of one solve). Above glibc's mmap
        threshold (32 MB: 1.5x10^6 points) every fresh array is new pages
        that the kernel must zero; reused, it is not."""
        a = self._scratch.get(name)
        if a is None or a.shape != tuple(shape):
            a = self._scratch[name] = np.empty(shape)
        return a


def _taken():
    """Owner of a buffer handed out and not yet given to a system."""
    return True
