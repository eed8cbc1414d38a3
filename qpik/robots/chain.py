r"""Serial chains: FK, geometric Jacobian, kinematic Hessian, manipulability of any revolute/prismatic chain.

A :class:`SerialChain` is a list of :class:`~qpik.robots.joint.Joint` s. Joint *k* moves link *k* relative
to link *k-1*:

.. math:: F_k = F_{k-1}\,P_k\,M_k(q_k + o_k)\,S_k,\qquad F_0 = \mathrm{base},\quad F_{ee} = F_n\,\mathrm{tool},

with constant transforms :math:`P_k` (``pre``: link *k-1* to the joint frame, whose z axis is
the joint axis) and :math:`S_k` (``post``: the moved joint frame to link frame *k*), and the
motion :math:`M_k = R_z` (revolute, rad) or :math:`T_z` (prismatic, m). A DH table is one way
to fill these in (:class:`qpik.robots.dh.DHChain`); a MuJoCo model is another
(:mod:`qpik.robots.loader`, where :math:`S_k = I` and link frame *k* is the joint frame).

The expressions are written once in :mod:`qpik.algebra.symbolic` and evaluated three ways: numpy
over a batch, CasADi symbols, and a compiled CasADi function for one configuration (the
fast path, :mod:`qpik.native.compiled`). Constant 0 and ±1 entries fold away while tracing, so
an identity ``pre`` or ``post`` costs nothing.

A joint may be coupled (a URDF mimic joint): :math:`q_k = m\,q_i` for an independent joint *i*
before it (the constant part goes into its offset). The chain's configuration q then has one
entry per independent joint (:attr:`SerialChain.dof`), its frames one per joint, and each
Jacobian column of joint *i* is, by the chain rule, the sum of the columns of the joints it
drives, times their multipliers (and the Hessian's entries likewise in both indices).

Conventions: metres and radians; the geometric Jacobian rows are ``[v; ω]`` of the
end-effector origin, both in the chain's base frame (the frame ``base`` is given in; for a
catalog arm the world, for a loaded one its base link: :mod:`qpik.robots.loader`).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import casadi as ca
import numpy as np

from qpik.algebra import symbolic as sy
from qpik.algebra.symbolic import Frame, Ops, Scalar
from qpik.core.errors import InputError
from qpik.core.validate import flag, joint_vector, single_pose
from qpik.native.compiled import Compiled
from qpik.robots.joint import ZERO_VEC, Joint
from qpik.robots.manipulability import (
    hessian_rows,
    jacobian_rows,
    manipulability_gradient_expr,
    manipulability_gradient_from,
)


class SerialChain:
    """A serial chain of revolute and prismatic joints (immutable once built).

    Args:
        joints: the joints from the base outward.
        base: (4, 4) frame 0 in the chain's base frame (the frame of every pose it gives).
        tool: (4, 4) frame-n-from-end-effector transform.
    """

    joints: tuple[Joint, ...]
    base: np.ndarray
    tool: np.ndarray

    def __init__(self, joints: Sequence[Joint], base: np.ndarray | None = None, tool: np.ndarray | None = None):
        self._set(joints, base, tool)

    def _set(self, joints: Sequence[Joint], base: np.ndarray | None, tool: np.ndarray | None) -> None:
        """Check and store the joints, base and tool (also for frozen dataclass subclasses)."""
        cls = type(self).__name__
        try:
            joints = tuple(joints)
        except TypeError:
            raise InputError(f"{cls}.joints: expected a sequence of Joints, got {type(joints).__name__}") from None
        if not joints:
            raise InputError(f"{cls}.joints: a chain needs at least one joint")
        bad = [i for i, j in enumerate(joints) if not isinstance(j, Joint)]
        if bad:
            raise InputError(f"{cls}.joints[{bad[0]}]: expected a Joint, got {type(joints[bad[0]]).__name__}")
        independent = 0
        for k, j in enumerate(joints):
            if j.mimic is None:
                independent += 1
            elif j.mimic[0] >= independent:
                raise InputError(f"{cls}.joints[{k}]: mimics independent joint {j.mimic[0]}, which is not before it")
        if not independent:
            raise InputError(f"{cls}.joints: a chain needs at least one independent joint")
        object.__setattr__(self, "joints", joints)
        for name, T in (("base", base), ("tool", tool)):
            object.__setattr__(self, name, np.eye(4) if T is None else single_pose(T, f"{cls}.{name}"))

    def __getstate__(self) -> dict:
        """The chain's numbers without its cached CasADi functions and compiled code (rebuilt on first use after
        unpickling): a chain pickles to another process or machine (:mod:`qpik.robots.bundle`)."""
        cached = {n for k in type(self).__mro__ for n, v in vars(k).items() if isinstance(v, cached_property)}
        return {k: v for k, v in self.__dict__.items() if k not in cached}

    @cached_property
    def dof(self) -> int:
        """The number of independent joints: the length of q."""
        return sum(j.mimic is None for j in self.joints)

    @cached_property
    def coupling(self) -> tuple[tuple[int, float], ...]:
        """Per chain joint k: ``(i, m)``, its q is m times q[i] (``(i, 1.0)`` for independent joint i)."""
        out, i = [], 0
        for j in self.joints:
            if j.mimic is None:
                out.append((i, 1.0))
                i += 1
            else:
                out.append(j.mimic)
        return tuple(out)

    def _contract(self, cols: list, zero: sy.Vec) -> list:
        """Per-joint columns (one per chain joint) -> per-q columns (chain rule); identity without couplings."""
        if len(self.joints) == self.dof:
            return cols
        out: list = [None] * self.dof
        for (i, m), c in zip(self.coupling, cols):
            c = c if m == 1.0 else sy.vscale(m, c)
            out[i] = c if out[i] is None else sy.vadd(out[i], c)
        return [zero if c is None else c for c in out]

    def _full_q(self, q: list[Scalar]) -> list[Scalar]:
        """Each chain joint's variable from the independent q."""
        return [q[i] if m == 1.0 else sy.mul(m, q[i]) for i, m in self.coupling]

    @cached_property
    def prismatic(self) -> np.ndarray:
        """(n,) bool, True for the prismatic independent joints."""
        return np.array([j.kind == "prismatic" for j in self.joints if j.mimic is None])

    # ---- the one definition -------------------------------------------------

    def frames_expr(self, q: list[Scalar], ops: Ops) -> list[Frame]:
        """Frames 0..n and the end-effector, as :mod:`qpik.algebra.symbolic` frames.

        Returns ``len(joints) + 2`` frames: ``[base, frame_1, ..., frame_n, ee]`` (n + 2 without mimic joints);
        ``q`` has :attr:`dof` entries.
        """
        frames = [sy.frame_of(self.base)]
        for joint, qi in zip(self.joints, self._full_q(q)):
            frames.append(sy.compose(frames[-1], joint.local_expr(qi, ops)))
        frames.append(sy.compose(frames[-1], sy.frame_of(self.tool)))
        return frames

    def axes_expr(self, frames: list[Frame]) -> list[tuple[sy.Vec, sy.Vec]]:
        """Joint axes as (unit axis z_i, point o_i on the axis), world frame, from :meth:`frames_expr`'s frames."""
        out = []
        for k, joint in enumerate(self.joints, start=1):
            if joint.axis_source == "before":
                R, p = frames[k - 1]
            elif joint.axis_source == "after":
                R, p = frames[k]  # a revolute motion keeps the axis; S moves only along it
            else:
                R, p = sy.compose(frames[k - 1], sy.frame_of(joint.pre))
            out.append((sy.col(R, 2), p))
        return out

    def point_jacobian_expr(self, frames: list[Frame], point: sy.Vec, link: int) -> list[sy.Vec]:
        r"""Columns of the translational Jacobian of a world point rigidly attached to link ``link`` (1..n).

        A revolute joint ``j`` turns about the unit axis :math:`z_j` through :math:`o_j` (world
        frame), a prismatic one slides along :math:`z_j`, so
        :math:`\dot p = \sum_{j \le link} c_j\,\dot q_j` with :math:`c_j = z_j \times (p - o_j)`
        or :math:`z_j`; returns the columns of q's entries up to the last independent joint at or before ``link``
        (``link`` columns without mimic joints; the joints beyond do not move it).
        """
        cols = []
        for joint, (z, o) in zip(self.joints[:link], self.axes_expr(frames)[:link]):
            cols.append(z if joint.kind == "prismatic" else sy.cross(z, sy.vsub(point, o)))
        if len(self.joints) == self.dof:
            return cols
        used = max(i for i, _ in self.coupling[:link]) + 1
        return self._contract(cols + [ZERO_VEC] * (len(self.joints) - link), ZERO_VEC)[:used]

    def jacobian_expr(self, frames: list[Frame]) -> tuple[list[sy.Vec], list[sy.Vec]]:
        """Columns of the geometric Jacobian: (linear parts, angular parts); a prismatic joint's angular part is 0."""
        jv = self.point_jacobian_expr(frames, frames[-1][1], len(self.joints))
        jw = [ZERO_VEC if j.kind == "prismatic" else z for j, (z, _) in zip(self.joints, self.axes_expr(frames))]
        return jv, self._contract(jw, ZERO_VEC)

    def hessian_expr(
        self, frames: list[Frame], jacobian: tuple[list[sy.Vec], list[sy.Vec]] | None = None
    ) -> list[list[tuple[sy.Vec, sy.Vec]]]:
        r"""Kinematic Hessian: ``H[k][j] = ∂J[:, j]/∂q_k`` as (linear, angular) parts.

        With the Jacobian columns :math:`J_{v,i}`, :math:`J_{\omega,i}` (:math:`J_{\omega,i} = z_i`
        for a revolute joint, 0 for a prismatic one):
        :math:`∂J_{v,j}/∂q_k = J_{\omega,\min(j,k)} \times J_{v,\max(j,k)}`, and
        :math:`∂J_{\omega,j}/∂q_k = J_{\omega,k} \times J_{\omega,j}` for :math:`k < j`, else 0.
        ``jacobian``: the columns of :meth:`jacobian_expr` if the caller has them already. With mimic joints the
        per-joint Hessian is contracted in both indices (the chain rule; the couplings are linear).
        """
        if len(self.joints) != self.dof:
            return self._hessian_coupled(frames)
        jv, jw = self.jacobian_expr(frames) if jacobian is None else jacobian
        H = []
        for k in range(self.dof):
            row = []
            for j in range(self.dof):
                lo, hi = min(j, k), max(j, k)
                hv = sy.cross(jw[lo], jv[hi])
                hw = sy.cross(jw[k], jw[j]) if k < j else ZERO_VEC
                row.append((hv, hw))
            H.append(row)
        return H

    def _hessian_coupled(self, frames: list[Frame]) -> list[list[tuple[sy.Vec, sy.Vec]]]:
        """:meth:`hessian_expr` of a chain with mimic joints: the per-joint Hessian, contracted."""
        m = len(self.joints)
        axes = self.axes_expr(frames)
        p = frames[-1][1]
        jv = [z if j.kind == "prismatic" else sy.cross(z, sy.vsub(p, o)) for j, (z, o) in zip(self.joints, axes)]
        jw = [ZERO_VEC if j.kind == "prismatic" else z for j, (z, _) in zip(self.joints, axes)]
        zero = (ZERO_VEC, ZERO_VEC)
        H = [[zero] * self.dof for _ in range(self.dof)]
        for k in range(m):
            a, ma = self.coupling[k]
            for j in range(m):
                b, mb = self.coupling[j]
                lo, hi = min(j, k), max(j, k)
                hv = sy.vscale(ma * mb, sy.cross(jw[lo], jv[hi]))
                hw = sy.vscale(ma * mb, sy.cross(jw[k], jw[j])) if k < j else ZERO_VEC
                H[a][b] = (sy.vadd(H[a][b][0], hv), sy.vadd(H[a][b][1], hw))
        return H

    # ---- CasADi -------------------------------------------------------------

    @cached_property
    def casadi_functions(self) -> dict[str, ca.Function]:
        """CasADi functions of ``q`` (n,): ``fk`` -> (4,4), ``jacobian`` -> (6,n),
        ``fk_jacobian`` -> both, ``frames`` -> (4, 4*(n+2)) side by side,
        ``hessian`` -> (6*n, n) with rows ``[k*6:(k+1)*6]`` = ∂J/∂q_k,
        ``manipulability_gradient`` -> ∇m (n,) and the translational ∇m (n,)."""
        q = ca.SX.sym("q", self.dof)
        frames = self.frames_expr([q[i] for i in range(self.dof)], sy.CASADI)
        T = _frame_to_sx(frames[-1])
        jv, jw = self.jacobian_expr(frames)
        J = ca.horzcat(*[ca.vertcat(*v, *w) for v, w in zip(jv, jw)])
        H = self.hessian_expr(frames, (jv, jw))
        Hs = ca.vertcat(*[ca.horzcat(*[ca.vertcat(*hv, *hw) for hv, hw in row]) for row in H])
        F = ca.horzcat(*[_frame_to_sx(f) for f in frames])
        Jr, Hr = jacobian_rows(jv, jw), hessian_rows(H)
        grad = [manipulability_gradient_expr(Jr[:rows], [Hk[:rows] for Hk in Hr])[0] for rows in (6, 3)]
        return {
            "fk": ca.Function("fk", [q], [T]),
            "jacobian": ca.Function("jacobian", [q], [J]),
            "fk_jacobian": ca.Function("fk_jacobian", [q], [T, J]),
            "frames": ca.Function("frames", [q], [F]),
            "hessian": ca.Function("hessian", [q], [Hs]),
            "manipulability_gradient": ca.Function(
                "manipulability_gradient", [q], [ca.vertcat(*grad[0]), ca.vertcat(*grad[1])]
            ),
        }

    @cached_property
    def _compiled(self) -> dict[str, Compiled]:
        """The fast single-q evaluators of :attr:`casadi_functions`, each built on first use."""
        return _LazyCompiled(self.casadi_functions)

    @cached_property
    def _fresh(self) -> dict:
        """``name -> fresh(q)`` of the compiled extension (:meth:`qpik.native.fastcall.Kernel.fresh`: q checked in C,
        new row-major outputs; None for any q it does not take), or ``name -> None`` without the extension."""
        return _LazyFresh(self._compiled)

    # ---- numeric API --------------------------------------------------------

    def _batch(self, q: np.ndarray) -> list[Frame]:
        return self.frames_expr([q[:, i] for i in range(self.dof)], sy.NUMPY)

    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector pose in the chain's base frame: q (n,) -> (4, 4); q (N, n) -> (N, 4, 4)."""
        fast = self._fresh["fk"]
        if fast is not None and (out := fast(q)) is not None:
            return out[0]
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["fk"].copies(q)[0]
        rows = [] if fast is None else [fast(row) for row in np.ascontiguousarray(q)]
        if rows and all(out is not None for out in rows):
            return np.stack([out[0] for out in rows])  # the compiled pose, row by row: faster than numpy's batch
        return _frame_to_np(self._batch(q)[-1], len(q))

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Base-frame poses of ``[base, frame_1..frame_n, ee]``: (n+2, 4, 4) or (N, n+2, 4, 4) (n: every chain
        joint, mimic joints included)."""
        q, batched = joint_vector(q, self.dof)
        if not batched:
            F = self._compiled["frames"].copies(q)[0]
            return F.reshape(4, len(self.joints) + 2, 4).transpose(1, 0, 2).copy()
        fr = self._batch(q)
        return np.stack([_frame_to_np(f, len(q)) for f in fr], axis=1)

    def axes(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint axes at q (n,), base frame: unit directions and a point on each axis, (len(joints), 3) each, m."""
        q, batched = joint_vector(q, self.dof)
        if batched:
            raise InputError(f"q: expected shape ({self.dof},), got {q.shape}")
        axes = self.axes_expr(self._batch(q[None]))
        z, o = ([sy.stack(list(v[i]), sy.NUMPY, (1,))[0] for v in axes] for i in (0, 1))
        return np.array(z), np.array(o)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian ``[v; ω]`` (base frame): (6, n) or (N, 6, n)."""
        fast = self._fresh["jacobian"]
        if fast is not None and (out := fast(q)) is not None:
            return out[0] if self.dof > 1 else out[0].reshape(6, 1)  # (a one-column output comes flat)
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["jacobian"].copies(q)[0].reshape(6, self.dof)
        return self._jac_np(self._batch(q), len(q))

    def fk_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pose and Jacobian together (one kinematics pass)."""
        fast = self._fresh["fk_jacobian"]
        if fast is not None and (out := fast(q)) is not None:
            return out if self.dof > 1 else (out[0], out[1].reshape(6, 1))  # (a one-column output comes flat)
        q, batched = joint_vector(q, self.dof)
        if not batched:
            T, J = self._compiled["fk_jacobian"].copies(q)
            return T, J.reshape(6, self.dof)
        fr = self._batch(q)
        return _frame_to_np(fr[-1], len(q)), self._jac_np(fr, len(q))

    def _jac_np(self, fr: list[Frame], n: int) -> np.ndarray:
        jv, jw = self.jacobian_expr(fr)
        cols = [sy.stack([*v, *w], sy.NUMPY, (n,)) for v, w in zip(jv, jw)]
        return np.stack(cols, axis=-1)

    def hessian(self, q: np.ndarray) -> np.ndarray:
        """Kinematic Hessian ``H[..., k, :, j] = ∂J[:, j]/∂q_k``: (n, 6, n) or (N, n, 6, n)."""
        q, batched = joint_vector(q, self.dof)
        n = self.dof
        if not batched:
            return self._compiled["hessian"].copies(q)[0].reshape(n, 6, n)
        H = self.hessian_expr(self._batch(q))
        return np.stack(
            [np.stack([sy.stack([*hv, *hw], sy.NUMPY, (len(q),)) for hv, hw in row], axis=-1) for row in H],
            axis=1,
        )

    def manipulability(self, q: np.ndarray, translational: bool = False) -> np.ndarray | float:
        """Yoshikawa's index sqrt(det(J Jᵀ)) (Zheng et al. 2019, eq. 6); ``translational`` uses J[:3].

        Returns a float for q (n,) and an array (N,) for q (N, n); 0 for a chain of fewer joints than rows.
        """
        J = self.jacobian(q)
        if flag(translational, "translational"):
            J = J[..., :3, :]
        if J.shape[-2] > self.dof:  # fewer joints than rows: det(J Jᵀ) = 0
            return 0.0 if J.ndim == 2 else np.zeros(len(J))
        # Jᵀ = QR gives det(J Jᵀ) = det(RᵀR) = Π R_ii²; unlike det(J Jᵀ), which squares the
        # condition number, this keeps m accurate to ~ε·σ_max near singular configurations
        R = np.linalg.qr(np.swapaxes(J, -1, -2), mode="r")
        m = np.abs(np.prod(np.diagonal(R, axis1=-2, axis2=-1), axis=-1))
        return float(m) if m.ndim == 0 else m

    def manipulability_gradient(self, q: np.ndarray, translational: bool = False) -> np.ndarray:
        r"""∂m/∂q (per rad) from the kinematic Hessian: (n,) or (N, n); see
        :func:`~qpik.robots.manipulability.manipulability_gradient_expr`.

        One configuration goes through the compiled function, a batch through numpy.
        """
        which = int(flag(translational, "translational"))
        fast = self._fresh["manipulability_gradient"]
        if fast is not None and (out := fast(q)) is not None:
            return out[which]
        q, batched = joint_vector(q, self.dof)
        if not batched:
            return self._compiled["manipulability_gradient"].copies(q)[which]
        return manipulability_gradient_from(self.jacobian(q), self.hessian(q), translational)


class _LazyCompiled(dict):
    """``name -> Compiled(functions[name])``, compiled when first asked for."""

    def __init__(self, functions: dict[str, ca.Function]):
        super().__init__()
        self.functions = functions

    def __missing__(self, name: str) -> Compiled:
        self[name] = Compiled(self.functions[name])
        return self[name]


class _LazyFresh(dict):
    """``name -> Kernel.fresh`` of ``compiled[name]`` (or None without the extension), made when first asked for."""

    def __init__(self, compiled: dict[str, Compiled]):
        super().__init__()
        self.compiled = compiled

    def __missing__(self, name: str):
        kernel = self.compiled[name].fast()
        self[name] = None if kernel is None else kernel.fresh
        return self[name]


def _frame_to_sx(f: Frame) -> ca.SX:
    R, p = f
    rows = [ca.horzcat(*R[i], p[i]) for i in range(3)]
    return ca.vertcat(*rows, ca.DM([[0, 0, 0, 1]]))


def _frame_to_np(f: Frame, n: int) -> np.ndarray:
    R, p = f
    T = np.zeros((n, 4, 4))
    for i in range(3):
        for j in range(3):
            T[:, i, j] = R[i][j]
        T[:, i, 3] = p[i]
    T[:, 3, 3] = 1.0
    return T
