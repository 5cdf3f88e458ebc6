"""Ids of moving points at exposures (``P1@007``) and the time order of
exposures; light, so that Monte-Carlo workers import it cheaply."""

from __future__ import annotations

import numpy as np


def split_id(ident) -> tuple[str, str]:
    """``"P1@007"`` -> ``("P1", "007")``; ids without an exposure -> (id, "")."""
    name, _, exposure = str(ident).partition("@")
    return name, exposure


def exposure_order(exposures):
    """Exposure ids in time order, and their frame numbers (numeric ids are
    frame numbers; others are taken in order of appearance)."""
    ids = list(dict.fromkeys(exposures))
    try:
        frames = np.array([int(e) for e in ids])
        order = np.argsort(frames, kind="stable")
        return [ids[i] for i in order], frames[order]
    except ValueError:
        return ids, np.arange(len(ids))
