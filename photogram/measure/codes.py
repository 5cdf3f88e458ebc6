"""Ring-coded targets: a central dot inside a ring of dark arcs.

The coded marks of the PhotoModeler calibration sheet (and similar sheets)
are a dot surrounded by a ring divided into equal sectors, each inked or
blank: a cyclic bit string (the sheet's four marks have 8 sectors of 45 deg:
``11111000``, ``11001100``, ``10010100``, ``10101010``; measured on the
CAMCAL photographs, docs/measure.md). The decoder samples the ring of
every detected dot **in the dot's own normalised frame**: the fitted ellipse of the dot maps to the unit
circle, which removes the affine part of the perspective (an affinity that
maps a circle onto a circle is a similarity, so angles along the ring are
the sheet's angles up to a rotation; the orientation sense is kept because
the sheet is seen from its front). The ring is sampled at 1 deg steps on
several radii between the inner and outer ring radius (in dot radii) and
binarised at the mid level between the dot's background and its ink (the
levels of the dot's own edge fit, so uneven light does not matter).

Decoding is rotation-invariant template matching: the binary profile is
compared with each code's template at all 360 rotations; the score is the
fraction of agreeing samples. A dot is

* *plain* when its ring holds (almost) no ink and the annulus between dot
  and ring is clear,
* *decoded* as code k when the best score is at least ``min_score`` and
  exceeds every other code's best by at least ``margin``,
* *rejected* (counted, never guessed) otherwise: a partial ring at the
  image border, a neighbouring code's arc, a reflection.

The four codes of the sheet differ from each other (at their best
rotation) in at least 2 of 8 sectors, 90 deg of ring. With ``min_score``
0.9 and ``margin`` 0.1 a wrong code is accepted only if the profile is
within 36 deg of it and at least 72 deg away from the right one, i.e.
after a corruption of 72 deg or more of the ring; smaller corruptions
(blur, ink spread, noise, a partly hidden ring) decode right or are
rejected (tests/test_measure_field.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RingCode", "ring_profiles", "decode_rings"]


@dataclass(frozen=True)
class RingCode:
    """One ring code: ``bits`` is the cyclic pattern of inked (1) and blank
    (0) sectors of equal size, read in the image's clockwise sense
    (x right, y down) on the sheet seen from the front."""

    id: str
    bits: str

    def template(self, n: int = 360) -> np.ndarray:
        """Binary ring profile (n,) starting at the first sector."""
        k = len(self.bits)
        sector = ((np.arange(n) + 0.5) * k / n).astype(int)
        return np.array([b == "1" for b in self.bits])[sector]


def ring_profiles(t: np.ndarray, xy: np.ndarray, axes: np.ndarray, angle: np.ndarray,
                  background: np.ndarray, contrast: np.ndarray,
                  radii=(2.9, 3.3, 3.7), clear=(1.5, 2.1), n: int = 360):
    """Binary ring profiles of dots and the ink fraction of their clear annulus.

    Parameters
    ----------
    t : image with bright targets (float32)
    xy, axes, angle : the fitted ellipses of the dots (centre, semi-axes, angle)
    background, contrast : grey levels of each dot's surroundings and ink
    radii : ring radii in dot radii (sampled and voted)
    clear : radii of the annulus that must be free of ink around a code's dot

    Returns
    -------
    ring : (m, n) bool      ink along the ring (majority over ``radii``)
    inside_ink : (m,) float ink fraction of the clear annulus
    valid : (m,) bool       every ring sample inside the image
    """
    import cv2
    m = len(xy)
    h, w = t.shape
    phi = (np.arange(n) + 0.5) * 2 * np.pi / n
    rho = np.concatenate([np.asarray(radii, float), np.linspace(*clear, 3)])
    ct, st = np.cos(angle), np.sin(angle)
    A, B = axes[:, 0], axes[:, 1]
    cx = A[:, None, None] * rho[None, :, None] * np.cos(phi)[None, None, :]
    cy = B[:, None, None] * rho[None, :, None] * np.sin(phi)[None, None, :]
    X = xy[:, 0, None, None] + cx * ct[:, None, None] - cy * st[:, None, None]
    Y = xy[:, 1, None, None] + cx * st[:, None, None] + cy * ct[:, None, None]
    valid = ((X >= 0) & (X <= w - 1) & (Y >= 0) & (Y <= h - 1)).all(axis=(1, 2))
    v = cv2.remap(t, X.reshape(m * len(rho), n).astype(np.float32),
                  Y.reshape(m * len(rho), n).astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE).reshape(m, len(rho), n)
    ink = v > (background + 0.5 * contrast)[:, None, None]
    k = len(radii)
    ring = ink[:, :k].sum(axis=1) * 2 > k
    inside = ink[:, k:].mean(axis=(1, 2))
    return ring, inside, valid


def decode_rings(ring: np.ndarray, inside_ink: np.ndarray, valid: np.ndarray,
                 codes: list[RingCode], *, min_score: float = 0.9, margin: float = 0.1,
                 plain_ink: float = 0.03):
    """Decode ring profiles (module doc).

    Returns
    -------
    label : (m,) object   code id, "" for a plain dot, None for a rejected ring
    score : (m,) float    best template score (NaN for plain dots)
    """
    m, n = ring.shape
    label = np.full(m, "", dtype=object)
    score = np.full(m, np.nan)
    frac = ring.mean(axis=1)
    coded = frac > plain_ink
    if not codes:
        return label, score
    idx = np.nonzero(coded)[0]
    if len(idx) == 0:
        return label, score
    # circular agreement of each profile with every rotation of each template
    P = np.fft.rfft(np.where(ring[idx], 1.0, -1.0), axis=1)
    best = np.empty((len(idx), len(codes)))
    for j, code in enumerate(codes):
        T = np.fft.rfft(np.where(code.template(n), 1.0, -1.0))
        corr = np.fft.irfft(P * np.conj(T)[None, :], n=n, axis=1)   # sum of +-1 products
        best[:, j] = (corr.max(axis=1) / n + 1) / 2
    order = np.argsort(-best, axis=1)
    top = best[np.arange(len(idx)), order[:, 0]]
    second = best[np.arange(len(idx)), order[:, 1]] if len(codes) > 1 else np.zeros(len(idx))
    ok = (top >= min_score) & (top - second >= margin) & valid[idx] & (inside_ink[idx] < 0.1)
    for i, k, good, s in zip(idx, order[:, 0], ok, top):
        label[i] = codes[k].id if good else None
        score[i] = s
    return label, score
