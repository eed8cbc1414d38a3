"""Input checking shared by every public function.

All checks raise :class:`qpik.core.errors.InputError` (a ``ValueError``) with a
message that names the argument. A compiled extension may install checks in C for the common inputs (one
float64 joint vector, one float64 pose: :func:`install_checks`, done by :mod:`qpik.native.fastcall` when it
loads); an input they do not accept takes the general path, which decides.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from qpik.core.errors import InputError, RotationError

ORTHONORMAL_TOL = 1e-6
PROJECT_TOL = 0.5
"""``project=True`` accepts a matrix whose singular values all lie within this of 1 and whose
determinant is > 0: a rotation with rounding error (a matrix that is singular, a reflection or
far from orthonormal is not one, and raises :class:`RotationError`)."""
MAX_LENGTH = 1e6
"""m: positions and lengths beyond this are rejected (their squares, and the feasible-interval
polynomials of degree 8 in them, would lose every digit or overflow float64)."""


@dataclass
class CompiledChecks:
    """The checks in C that :func:`joint_vector` and :func:`pose` try first (None: not installed).

    Attributes:
        vector_ok: ``vector_ok(q, n)``: True when q is a finite float64 vector (n,).
        pose_ok: ``pose_ok(T)``: True when T is a finite float64 (4, 4) pose that :func:`pose` accepts without
            projection.
    """

    vector_ok: Callable[[object, int], bool] | None = None
    pose_ok: Callable[[object], bool] | None = None


COMPILED = CompiledChecks()


def install_checks(vector_ok: Callable[[object, int], bool], pose_ok: Callable[[object], bool]) -> None:
    """Make :func:`joint_vector` and :func:`pose` try ``vector_ok`` and ``pose_ok`` first (see
    :class:`CompiledChecks`)."""
    COMPILED.vector_ok, COMPILED.pose_ok = vector_ok, pose_ok


def finite_array(x: object, name: str, shape: tuple[int | None, ...] | None = None) -> np.ndarray:
    """Return ``x`` as a float64 array, checking finiteness and (optionally) shape.

    ``shape`` may use ``None`` for a free dimension, e.g. ``(None, 7)``. Complex values,
    strings and other non-numbers raise :class:`InputError`.
    """
    if type(x) is np.ndarray and x.dtype == np.float64:
        arr = x  # fast path of the 1 kHz loops: no conversion
    else:
        try:
            raw = np.asarray(x)
            if raw.dtype.kind in "USc" or x is None:
                what = {"U": "text", "S": "bytes", "c": "complex values"}.get(raw.dtype.kind, "None")
                raise TypeError(f"{what} not accepted, got {x!r}"[:120])
            arr = raw.astype(float, copy=False)
        except (TypeError, ValueError, OverflowError) as exc:
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
    with np.errstate(over="ignore", invalid="ignore"):
        if flat.size and math.isfinite(flat @ flat):
            return True
    return bool(np.isfinite(arr).all())


def bounded(arr: np.ndarray, name: str, limit: float = MAX_LENGTH) -> np.ndarray:
    """``arr`` (already finite) if every ``|entry| <= limit`` (default :data:`MAX_LENGTH`, m), else InputError."""
    if arr.size and np.abs(arr).max() > limit:
        raise InputError(f"{name}: magnitude must be <= {limit:g} m, got {np.abs(arr).max():g}")
    return arr


def number(x: object, name: str, minimum: float | None = 0.0, finite: bool = True) -> float:
    """``x`` as a float: a real number (not a bool or a string), not NaN, ``>= minimum`` (None: any), finite if asked.

    Raises :class:`InputError` naming ``name``.
    """
    if isinstance(x, bool | str | bytes) or x is None:
        raise InputError(f"{name}: expected a number, got {x!r}")
    try:
        value = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name}: expected a number, got {x!r}") from None
    if math.isnan(value) or (finite and math.isinf(value)):
        raise InputError(f"{name}: must be {'finite' if finite else 'a number'}, got {value}")
    if minimum is not None and value < minimum:
        raise InputError(f"{name}: must be >= {minimum:g}, got {value:g}")
    return value


def count(x: object, name: str, minimum: int = 0) -> int:
    """``x`` as an int: an integer (Python or numpy, not a bool, a float or a string) ``>= minimum``.

    Raises :class:`InputError` naming ``name``.
    """
    if isinstance(x, bool | np.bool_) or not isinstance(x, int | np.integer):
        raise InputError(f"{name}: expected an integer, got {x!r}"[:200])
    if x < minimum:
        raise InputError(f"{name}: must be >= {minimum}, got {x}")
    return int(x)


def flag(x: object, name: str) -> bool:
    """``x`` if it is a bool (Python or numpy), else :class:`InputError` (``project="no"`` must not project)."""
    if isinstance(x, bool | np.bool_):
        return bool(x)
    raise InputError(f"{name}: expected True or False, got {x!r}")


def joint_vector(q: object, dof: int, name: str = "q") -> tuple[np.ndarray, bool]:
    """Check a joint vector ``(dof,)`` or batch ``(N, dof)``; return it and whether it is batched."""
    if (check := COMPILED.vector_ok) is not None and check(q, dof):  # one float64 vector, checked in C
        return q, False
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


def check_projectable(R: np.ndarray, name: str = "rotation") -> None:
    """Raise :class:`RotationError` unless every ``R`` (..., 3, 3) is a rotation with rounding error.

    That is: det > 0 and every singular value within :data:`PROJECT_TOL` of 1. A reflection, a
    singular or a far from orthonormal matrix is not a rotation, and its nearest rotation would be
    an arbitrary answer (``-R`` would project to a rotation of another orientation).
    """
    sv = np.linalg.svd(R, compute_uv=False)
    det = np.linalg.det(R)
    bad = (det <= 0.0) | (np.abs(sv - 1.0).max(axis=-1) > PROJECT_TOL)
    if np.any(bad):
        i = int(np.argmax(bad)) if bad.ndim else 0
        which = f" (first bad index {i})" if bad.ndim else ""
        d, s = np.ravel(det)[i], np.reshape(sv, (-1, 3))[i]
        raise RotationError(
            f"{name}: not a rotation{which}, so it cannot be projected onto SO(3): det = {d:.3g}, "
            f"singular values {np.array2string(s, precision=3)} (a rotation with rounding error has det > 0 "
            f"and singular values within {PROJECT_TOL:g} of 1)"
        )


def pose(T: object, name: str = "pose", project: bool = False) -> tuple[np.ndarray, bool]:
    """Check a homogeneous pose ``(4, 4)`` or batch ``(N, 4, 4)`` (an empty batch ``(0, 4, 4)`` is one).

    The rotation block must be orthonormal with det +1 within
    ``ORTHONORMAL_TOL``, unless ``project=True``, in which case a rotation with rounding
    error is replaced by the nearest rotation (:func:`project_to_so3`; a reflection, a
    singular or a far from orthonormal matrix raises :class:`RotationError`, :func:`check_projectable`).
    The last row must be ``[0, 0, 0, 1]`` (within 1e-12); positions within
    :data:`MAX_LENGTH` m. Returns a new array and whether it is batched.
    """
    if project is False and (check := COMPILED.pose_ok) is not None and check(T):  # one pose, checked in C
        return T.copy(), False
    project = flag(project, "project")
    arr = np.array(finite_array(T, name), dtype=float)  # a copy: projection writes into it
    if arr.shape[-2:] != (4, 4) or arr.ndim not in (2, 3):
        raise InputError(f"{name}: expected shape (4, 4) or (N, 4, 4), got {arr.shape}")
    if not arr.size:
        return arr, True
    if (np.abs(arr[..., 3, :] - _LAST_ROW).max() if arr.ndim == 3 else _last_row_defect(arr)) > 1e-12:
        raise InputError(f"{name}: last row must be [0, 0, 0, 1]")
    if (np.abs(arr[..., :3, 3]).max() if arr.ndim == 3 else _position_size(arr)) > MAX_LENGTH:
        raise InputError(f"{name}: position magnitude must be <= {MAX_LENGTH:g} m")
    R = arr[..., :3, :3]
    if project:
        check_projectable(R, name)
        arr[..., :3, :3] = project_to_so3(R)
        return arr, arr.ndim == 3
    bad = _rotation_defect(R) > ORTHONORMAL_TOL if arr.ndim == 3 else _rotation_defect_one(R) > ORTHONORMAL_TOL
    if bad.any() if arr.ndim == 3 else bad:
        i = int(np.argmax(bad)) if arr.ndim == 3 else 0
        which = "" if arr.ndim == 2 else f" (first bad index {i})"
        det = float(np.linalg.det(R[i] if arr.ndim == 3 else R))
        hint = (
            f"det = {det:.3g}: not a rotation (a reflection or singular), projection cannot fix it"
            if det <= 0.0
            else "pass project=True to project it onto SO(3)"
        )
        raise RotationError(f"{name}: rotation is not orthonormal within {ORTHONORMAL_TOL:g}{which}; {hint}")
    return arr, arr.ndim == 3


def single_pose(T: object, name: str = "pose", project: bool = False) -> np.ndarray:
    """:func:`pose` of exactly one pose (4, 4); a batch raises :class:`InputError` naming ``name``."""
    arr, batched = pose(T, name, project)
    if batched:
        raise InputError(f"{name}: expected one pose (4, 4), got {arr.shape}")
    return arr


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def _last_row_defect(T: np.ndarray) -> float:
    a, b, c, d = T[3].tolist()
    return max(abs(a), abs(b), abs(c), abs(d - 1.0))


def _position_size(T: np.ndarray) -> float:
    (_, _, _, x), (_, _, _, y), (_, _, _, z) = T[:3].tolist()
    return max(abs(x), abs(y), abs(z))


def _rotation_defect(R: np.ndarray) -> np.ndarray:
    """max(|RᵀR - I|, |det R - 1|) per rotation of a batch (N, 3, 3).

    Entry by entry on (N,) arrays (Gram matrix of the columns, det as the triple
    product): a batched 3x3 matmul and ``np.cross`` cost several times more.
    """
    a, b, c = np.moveaxis(R, -1, 0)  # columns, each (N, 3)
    a, b, c = a.T, b.T, c.T  # (3, N): rows of contiguous component arrays
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: an inf defect is the answer
        err = np.abs(a[0] * a[0] + a[1] * a[1] + a[2] * a[2] - 1.0)
        for x, y, one in ((b, b, 1.0), (c, c, 1.0), (a, b, 0.0), (a, c, 0.0), (b, c, 0.0)):
            np.maximum(err, np.abs(x[0] * y[0] + x[1] * y[1] + x[2] * y[2] - one), out=err)
        det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        det += a[2] * (b[0] * c[1] - b[1] * c[0])
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
