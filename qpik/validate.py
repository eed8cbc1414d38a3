"""Input checking shared by every public function.

All checks raise :class:`qpik.errors.InputError` (a ``ValueError``) with a
message that names the argument.
"""

from __future__ import annotations

import math

import numpy as np

from qpik.errors import InputError, RotationError

ORTHONORMAL_TOL = 1e-6


def finite_array(x: object, name: str, shape: tuple[int | None, ...] | None = None) -> np.ndarray:
    """Return ``x`` as a float64 array, checking finiteness and (optionally) shape.

    ``shape`` may use ``None`` for a free dimension, e.g. ``(None, 7)``.
    """
    if type(x) is np.ndarray and x.dtype == np.float64:
        arr = x  # fast path of the 1 kHz loops: no conversion
    else:
        try:
            arr = np.asarray(x, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InputError(f"{name}: cannot be read as a float array ({exc})") from None
    if shape is not None:
        ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
        if not ok:
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            raise InputError(f"{name}: expected shape {want}, got {arr.shape}")
    if not _all_finite(arr):
        raise InputError(f"{name}: contains NaN or inf")
    return arr


def _all_finite(arr: np.ndarray) -> bool:
    """Whether every entry is finite; a vector is checked by one dot product.

    ``flat @ flat`` is a sum of squares: it is NaN or inf when any entry is (no
    cancellation is possible), so a finite result proves every entry finite.
    Only when it is not finite (or overflowed) is the element-wise test run.
    """
    flat = arr.ravel()
    if flat.size and math.isfinite(flat @ flat):
        return True
    return bool(np.isfinite(arr).all())


def joint_vector(q: object, dof: int, name: str = "q") -> tuple[np.ndarray, bool]:
    """Check a joint vector ``(dof,)`` or batch ``(N, dof)``; return it and whether it is batched."""
    arr = finite_array(q, name)
    if arr.ndim == 1 and arr.shape[0] == dof:
        return arr, False
    if arr.ndim == 2 and arr.shape[1] == dof:
        return arr, True
    raise InputError(f"{name}: expected shape ({dof},) or (N, {dof}), got {arr.shape}")


def project_to_so3(R: np.ndarray) -> np.ndarray:
    """Nearest rotation (Frobenius norm) to ``R`` (..., 3, 3), by SVD with det fixed to +1."""
    U, _, Vt = np.linalg.svd(R)
    D = np.ones(R.shape[:-1])
    D[..., -1] = np.sign(np.linalg.det(U @ Vt))
    return (U * D[..., None, :]) @ Vt


def pose(T: object, name: str = "pose", project: bool = False) -> tuple[np.ndarray, bool]:
    """Check a homogeneous pose ``(4, 4)`` or batch ``(N, 4, 4)``.

    The rotation block must be orthonormal with det +1 within
    ``ORTHONORMAL_TOL``, unless ``project=True``, in which case it is replaced by
    the nearest rotation. The last row must be ``[0, 0, 0, 1]`` (within 1e-12).
    Returns a new array and whether it is batched.
    """
    arr = np.array(finite_array(T, name), dtype=float)  # a copy: projection writes into it
    if arr.shape[-2:] != (4, 4) or arr.ndim not in (2, 3):
        raise InputError(f"{name}: expected shape (4, 4) or (N, 4, 4), got {arr.shape}")
    if (np.abs(arr[..., 3, :] - _LAST_ROW).max() if arr.ndim == 3 else _last_row_defect(arr)) > 1e-12:
        raise InputError(f"{name}: last row must be [0, 0, 0, 1]")
    R = arr[..., :3, :3]
    if project:
        arr[..., :3, :3] = project_to_so3(R)
        return arr, arr.ndim == 3
    bad = _rotation_defect(R) > ORTHONORMAL_TOL if arr.ndim == 3 else _rotation_defect_one(R) > ORTHONORMAL_TOL
    if bad.any() if arr.ndim == 3 else bad:
        which = "" if arr.ndim == 2 else f" (first bad index {int(np.argmax(bad))})"
        raise RotationError(
            f"{name}: rotation is not orthonormal within {ORTHONORMAL_TOL:g}{which}; "
            "pass project=True to project it onto SO(3)"
        )
    return arr, arr.ndim == 3


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def _last_row_defect(T: np.ndarray) -> float:
    a, b, c, d = T[3].tolist()
    return max(abs(a), abs(b), abs(c), abs(d - 1.0))


def _rotation_defect(R: np.ndarray) -> np.ndarray:
    """max(|RᵀR - I|, |det R - 1|) per rotation of a batch (N, 3, 3).

    Entry by entry on (N,) arrays (Gram matrix of the columns, det as the triple
    product): a batched 3x3 matmul and ``np.cross`` cost several times more.
    """
    a, b, c = np.moveaxis(R, -1, 0)  # columns, each (N, 3)
    a, b, c = a.T, b.T, c.T  # (3, N): rows of contiguous component arrays
    err = np.abs(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] - 1.0)
    for x, y, one in ((b, b, 1.0), (c, c, 1.0), (a, b, 0.0), (a, c, 0.0), (b, c, 0.0)):
        np.maximum(err, np.abs(x[0] * y[0] + x[1] * y[1] + x[2] * y[2] - one), out=err)
    det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
    return np.maximum(err, np.abs(det - 1.0), out=err)


def _rotation_defect_one(R: np.ndarray) -> float:
    """The same for one (3, 3) rotation, in plain floats (numpy calls cost µs each here)."""
    (a, b, c), (d, e, f), (g, h, i) = R.tolist()
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
        abs(det - 1.0),
    )
