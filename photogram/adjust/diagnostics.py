"""Diagnostics of a failed or unconverged adjustment: where it went wrong."""

from __future__ import annotations

import numpy as np

__all__ = ["worst_observations"]


def worst_observations(problem, state, k=3):
    """``"; largest image residuals: stations S3 (rms 812), ...; points P7
    (rms 1.2e+03), ..."`` at ``state``: where a divergent or unconverged
    iteration went wrong (image units; non-finite residuals count as
    infinite)."""
    sums = {"station": {}, "point": {}}
    names = {"station": {}, "point": {}}
    for blk in problem.blocks:
        if blk.name != "image points":
            continue
        try:
            e, _ = blk.evaluate(state, False)
        except Exception:                               # noqa: BLE001 - message only
            return ""
        sq = np.sum(np.asarray(e, dtype=float) ** 2, axis=1)
        sq = np.where(np.isfinite(sq), sq, np.inf)
        labels = getattr(blk, "labels", None)
        for j, (key, idx) in enumerate((("station", blk.station), ("point", blk.point))):
            idx = np.asarray(idx, dtype=int)
            if labels is not None and len(labels) == len(idx):
                first = np.unique(idx, return_index=True)
                for i, r in zip(*first):
                    parts = str(labels[r]).split("/", 1)
                    if len(parts) == 2:
                        names[key].setdefault(int(i), parts[j])
            tot = np.bincount(idx, weights=np.where(np.isfinite(sq), sq, 0.0))
            inf = np.bincount(idx, weights=~np.isfinite(sq)) > 0
            cnt = np.bincount(idx)
            for i in np.flatnonzero(cnt):
                rms = np.inf if inf[i] else float(np.sqrt(tot[i] / cnt[i]))
                prev = sums[key].get(i, (0.0, 0))
                sums[key][i] = (max(prev[0], rms), cnt[i])
    parts = []
    for key, label in (("station", "stations"), ("point", "points")):
        worst = sorted(sums[key].items(), key=lambda kv: -kv[1][0])[:k]
        if not worst:
            continue
        nm = names[key]
        prefix = "S" if key == "station" else "P"
        items = [f"{nm.get(int(i), f'{prefix}#{i}')} (rms {v[0]:.3g})"
                 for i, v in worst]
        parts.append(f"{label} {', '.join(items)}")
    return ("; largest image residuals: " + "; ".join(parts)) if parts else ""
