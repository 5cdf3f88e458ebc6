"""Small differentiable functions with analytic Jacobians (forward mode).

A :class:`Q` carries a value and its Jacobian with respect to a fixed input
vector of ``m`` numbers, for ``n`` exposures at once:

* a vector: ``v`` (n, 3), ``J`` (n, 3, m);
* a scalar: ``v`` (n,), ``J`` (n, m).

Each function below returns the value and applies the chain rule with the
hand-derived derivative of that one step, so that any quantity composed of
them has an exact (analytic) Jacobian. Every step is tested against central
finite differences in tests/test_jump_propagate.py. Nothing is wrapped in
error handling: a degenerate configuration (zero vector, parallel vectors)
gives NaN or inf for that exposure only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Q", "inputs", "add", "sub", "scale", "mean", "dot", "cross", "norm",
           "normalize", "reject", "component", "neg", "atan2", "asin", "angle",
           "normalize_jacobian"]


@dataclass
class Q:
    """A value with its Jacobian (see the module docstring for shapes)."""

    v: np.ndarray
    J: np.ndarray

    @property
    def is_vector(self) -> bool:
        return self.v.ndim == 2


def inputs(blocks: list[np.ndarray]) -> list[Q]:
    """Independent inputs: each block (n, 3) gets an identity Jacobian in its
    own 3 columns of the ``m = 3 * len(blocks)`` columns."""
    n = blocks[0].shape[0]
    m = 3 * len(blocks)
    out = []
    for k, b in enumerate(blocks):
        J = np.zeros((n, 3, m))
        J[:, :, 3 * k:3 * k + 3] = np.eye(3)
        out.append(Q(np.asarray(b, dtype=float), J))
    return out


# ---------------------------------------------------------------------------
# linear steps


def add(a: Q, b: Q) -> Q:
    return Q(a.v + b.v, a.J + b.J)


def sub(a: Q, b: Q) -> Q:
    return Q(a.v - b.v, a.J - b.J)


def neg(a: Q) -> Q:
    return Q(-a.v, -a.J)


def scale(a: Q, c: float) -> Q:
    """``c * a`` for a constant ``c``."""
    return Q(c * a.v, c * a.J)


def mean(a: Q, b: Q) -> Q:
    return Q(0.5 * (a.v + b.v), 0.5 * (a.J + b.J))


def component(a: Q, i: int) -> Q:
    """Component ``i`` of a vector, as a scalar."""
    return Q(a.v[:, i], a.J[:, i, :])


# ---------------------------------------------------------------------------
# products and norms


def dot(a: Q, b: Q) -> Q:
    """``a . b``; ``d = b^T da + a^T db``."""
    v = np.einsum("ni,ni->n", a.v, b.v)
    J = np.einsum("ni,nim->nm", b.v, a.J) + np.einsum("ni,nim->nm", a.v, b.J)
    return Q(v, J)


def _skew(a: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[a]x`` (n, 3, 3): ``[a]x b = a x b``."""
    S = np.zeros(a.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -a[..., 2], a[..., 1]
    S[..., 1, 0], S[..., 1, 2] = a[..., 2], -a[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -a[..., 1], a[..., 0]
    return S


def cross(a: Q, b: Q) -> Q:
    """``a x b``; ``d = [a]x db - [b]x da``."""
    x, y = a.v, b.v                  # np.cross written out (slow on small arrays)
    v = np.empty(np.broadcast_shapes(x.shape, y.shape))
    v[..., 0] = x[..., 1] * y[..., 2] - x[..., 2] * y[..., 1]
    v[..., 1] = x[..., 2] * y[..., 0] - x[..., 0] * y[..., 2]
    v[..., 2] = x[..., 0] * y[..., 1] - x[..., 1] * y[..., 0]
    J = _skew(a.v) @ b.J - _skew(b.v) @ a.J
    return Q(v, J)


def norm(a: Q) -> Q:
    """``|a|``; ``d = a^T da / |a|``."""
    r = np.linalg.norm(a.v, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        J = np.einsum("ni,nim->nm", a.v / r[:, None], a.J)
    return Q(r, J)


def normalize_jacobian(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``u = a / |a|`` and ``du/da = (I - u u^T) / |a|`` for a stack (n, 3)."""
    r = np.linalg.norm(a, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = a / r[..., None]
        Jn = (np.eye(3) - u[..., :, None] * u[..., None, :]) / r[..., None, None]
    return u, Jn


def normalize(a: Q) -> Q:
    """``a / |a|``."""
    u, Jn = normalize_jacobian(a.v)
    return Q(u, Jn @ a.J)


def reject(a: Q, x: Q) -> Q:
    """The part of ``a`` orthogonal to the **unit** vector ``x``:
    ``q = a - (a.x) x``; ``dq = (I - x x^T) da - ((a.x) I + x a^T) dx``."""
    ax = np.einsum("ni,ni->n", a.v, x.v)
    q = a.v - ax[:, None] * x.v
    xxT = x.v[:, :, None] * x.v[:, None, :]
    A = np.eye(3) - xxT
    B = ax[:, None, None] * np.eye(3) + x.v[:, :, None] * a.v[:, None, :]
    return Q(q, A @ a.J - B @ x.J)


# ---------------------------------------------------------------------------
# angles


def atan2(y: Q, x: Q) -> Q:
    """``atan2(y, x)``; ``d = (x dy - y dx) / (x^2 + y^2)``."""
    r2 = x.v ** 2 + y.v ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        J = (x.v[:, None] * y.J - y.v[:, None] * x.J) / r2[:, None]
    return Q(np.arctan2(y.v, x.v), J)


def asin(s: Q) -> Q:
    """``asin(s)``; ``d = ds / sqrt(1 - s^2)``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        J = s.J / np.sqrt(1.0 - s.v ** 2)[:, None]
    return Q(np.arcsin(np.clip(s.v, -1.0, 1.0)), J)


def angle(a: Q, b: Q) -> Q:
    """Unsigned angle between two vectors in [0, pi]:
    ``atan2(|a x b|, a . b)`` (accurate at small and large angles)."""
    return atan2(norm(cross(a, b)), dot(a, b))
