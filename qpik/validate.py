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

    ``arr @ arr`` is a sum of squares: it is NaN or inf when any entry is (no
    cancellation is possible), so a finite result proves every entry finite.
    Only when it is not finite (or overflowed) is the element-wise test run.
    """
    if arr.ndim == 1 and math.isfinite(arr @ arr):
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
    the nearest rotation. The last row must be ``[0, 0, 0, 1]``.
    Returns a new array and whether it is batched.
    """
    arr = finite_array(T, name).copy()
    if arr.shape[-2:] != (4, 4) or arr.ndim not in (2, 3):
        raise InputError(f"{name}: expected shape (4, 4) or (N, 4, 4), got {arr.shape}")
    if not np.allclose(arr[..., 3, :], [0.0, 0.0, 0.0, 1.0], atol=1e-12):
        raise InputError(f"{name}: last row must be [0, 0, 0, 1]")
    R = arr[..., :3, :3]
    if project:
        arr[..., :3, :3] = project_to_so3(R)
    else:
        err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
        det = np.linalg.det(R)
        bad = (err > ORTHONORMAL_TOL) | (np.abs(det - 1.0) > ORTHONORMAL_TOL)
        if np.any(bad):
            which = "" if arr.ndim == 2 else f" (first bad index {int(np.argmax(bad))})"
            raise RotationError(
                f"{name}: rotation is not orthonormal within {ORTHONORMAL_TOL:g}{which}; "
                "pass project=True to project it onto SO(3)"
            )
    return arr, arr.ndim == 3
