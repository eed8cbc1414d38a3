r"""The record of one closed-loop run (:class:`SimLog`) and its summary figures.

Record *k* holds the state at time :math:`t_k` and the command issued there:
``q[k]`` is the configuration at ``t[k]``, ``v[k]`` the joint velocity the
policy returned for it (applied over the next step; the last record's command
is logged but not applied). Every pose is in the world (base) frame.

Tracking errors, against the target pose :math:`(R_d, p_d)`:

- position :math:`e_p = \lVert p_d - p \rVert` (m);
- orientation :math:`e_o = \angle(R_d^\top R)
  = \operatorname{atan2}(\lVert \operatorname{vee}(M - M^\top) \rVert,\ \operatorname{tr} M - 1)`
  with :math:`M = R_d^\top R` (rad, in [0, π]; exact near 0, unlike ``arccos``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from qpik.algebra.lie import tracking_errors


@dataclass
class Summary:
    """Headline figures of a :class:`SimLog` (see :meth:`SimLog.summary`).

    Attributes:
        label: the run's label.
        transient: seconds skipped at the start for the tracking-error maxima.
        max_pos_error, max_rot_error: after the transient (m, rad); NaN without a target.
        final_pos_error, final_rot_error: at the last record (m, rad); NaN without a target.
        min_clearance: per link, the smallest distance to any obstacle (m), shape (L,); empty without obstacles.
        max_limit_violation: the largest excursion past a joint limit (rad; 0 inside).
        min_limit_margin: the smallest distance to a joint limit (rad; negative when violated).
        max_velocity_ratio: max over time and joints of ``|v_i| / v_max_i`` (NaN without v_max).
        solve_time: mean, median, 99th percentile and max of the controller's solve time (s),
            empty when the policy reports none.
        statuses: count of each controller status, when the policy reports them.
        facts: the link–obstacle pairs left out of the clearances (:mod:`qpik.geometry.contacts`), in words.
    """

    label: str
    transient: float
    max_pos_error: float
    max_rot_error: float
    final_pos_error: float
    final_rot_error: float
    min_clearance: np.ndarray
    link_names: tuple[str, ...]
    max_limit_violation: float
    min_limit_margin: float
    max_velocity_ratio: float
    solve_time: dict[str, float] = field(default_factory=dict)
    statuses: dict[str, int] = field(default_factory=dict)
    facts: tuple[str, ...] = ()

    def __str__(self) -> str:
        lines = [f"{self.label}:"]
        if np.isfinite(self.max_pos_error):
            lines.append(
                f"  tracking error after {self.transient:g} s: max {self.max_pos_error * 1e3:.4g} mm,"
                f" {self.max_rot_error:.3g} rad; final {self.final_pos_error * 1e3:.4g} mm,"
                f" {self.final_rot_error:.3g} rad"
            )
        if self.min_clearance.size:
            per_link = ", ".join(f"{n} {d * 1e3:.1f}" for n, d in zip(self.link_names, self.min_clearance))
            lines.append(f"  min clearance (mm): {per_link}")
        lines += [f"  not checked: {f}" for f in self.facts]
        lines.append(
            f"  joint limits: min margin {self.min_limit_margin:.4g} rad, max violation {self.max_limit_violation:.3g}"
            f" rad; max |v|/v_max {self.max_velocity_ratio:.3g}"
        )
        if self.solve_time:
            st = self.solve_time
            lines.append(
                f"  solve time: mean {st['mean'] * 1e6:.0f} µs, median {st['median'] * 1e6:.0f} µs,"
                f" p99 {st['p99'] * 1e6:.0f} µs, max {st['max'] * 1e6:.0f} µs"
            )
        if self.statuses:
            lines.append("  status: " + ", ".join(f"{k} ×{n}" for k, n in self.statuses.items()))
        return "\n".join(lines)


@dataclass
class SimLog:
    """Arrays of one run; K records, n joints, L link geoms, O obstacles.

    Attributes:
        t: (K,) time (s).
        q: (K, n) joint positions (rad).
        v: (K, n) commanded joint velocities (rad/s).
        ee: (K, 4, 4) end-effector pose (site ``ee``) in the world frame.
        target: (K, 4, 4) target pose, or ``None`` when the run had no target.
        clearance: (K, L, O) signed distance (m) of each link geom to each obstacle,
            computed by MuJoCo (``mj_geomDistance``), independent of the controller.
            When geoms overlap it is MuJoCo's (negative) contact depth, which for a
            capsule in a box is not the same number as :func:`qpik.geometry.distances`.
        manipulability: (K,) Yoshikawa's sqrt(det(J Jᵀ)) from MuJoCo's site Jacobian.
        solve_time: (K,) controller solve time (s), NaN where not reported.
        status: (K,) controller status strings ('' where not reported).
        q_min, q_max: (n,) joint limits (rad); v_max: (n,) velocity limits (rad/s) or ``None``.
        link_names, obstacle_names: geom labels of the clearance axes.
        dt: integration step (s).
        d_safe: safety distance (m) to mark on clearance plots, or ``None``.
        label: a name for legends and summaries.
        robot: an object the model was built from (a :class:`qpik.Robot` or the MJCF kinematics),
            used to redraw the run.
        obstacles: the obstacle shapes of the run (world frame).
        checked: (L, O) bool, the pairs that count in :attr:`min_clearance` (:mod:`qpik.geometry.contacts`: not those
            whose distance no joint motion changes), or ``None``: every pair.
        facts: the pairs left out, each with its constant distance, in words.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    ee: np.ndarray
    target: np.ndarray | None
    clearance: np.ndarray
    manipulability: np.ndarray
    solve_time: np.ndarray
    status: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray | None
    link_names: tuple[str, ...]
    obstacle_names: tuple[str, ...]
    dt: float
    d_safe: float | None = None
    label: str = "run"
    robot: object = None
    obstacles: tuple = ()
    checked: np.ndarray | None = None
    facts: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.t)

    @property
    def errors(self) -> tuple[np.ndarray, np.ndarray]:
        """Position (m) and orientation (rad) tracking errors, (K,) each; NaN without a target."""
        if self.target is None:
            nan = np.full(len(self.t), np.nan)
            return nan, nan.copy()
        return tracking_errors(self.ee, self.target)

    @property
    def min_clearance(self) -> np.ndarray:
        """(K, L) distance of each link to its nearest obstacle over the checked pairs (m; inf for a link
        without one); (K, 0) without obstacles."""
        if self.clearance.shape[2] == 0:
            return np.zeros(self.clearance.shape[:2])[:, :0]
        if self.checked is None:
            return self.clearance.min(axis=2)
        return np.where(self.checked[None], self.clearance, np.inf).min(axis=2)

    @property
    def limit_margin(self) -> np.ndarray:
        """(K, n) distance to the nearer joint limit (rad); negative past a limit."""
        return np.minimum(self.q - self.q_min, self.q_max - self.q)

    def summary(self, transient: float = 0.5) -> Summary:
        """Headline figures; tracking-error maxima skip the first ``transient`` seconds."""
        e_pos, e_rot = self.errors
        after = self.t >= self.t[0] + transient
        if not after.any():
            after[-1] = True
        margin = self.limit_margin
        ratio = float(np.max(np.abs(self.v) / self.v_max)) if self.v_max is not None else float("nan")
        st = self.solve_time[np.isfinite(self.solve_time)]
        times = {}
        if st.size:
            times = {
                "mean": float(st.mean()),
                "median": float(np.median(st)),
                "p99": float(np.percentile(st, 99)),
                "max": float(st.max()),
            }
        kinds, counts = np.unique(self.status[self.status != ""], return_counts=True)
        min_clear = self.min_clearance.min(axis=0) if self.clearance.shape[2] else np.zeros(0)
        return Summary(
            label=self.label,
            transient=transient,
            max_pos_error=float(np.max(e_pos[after])),
            max_rot_error=float(np.max(e_rot[after])),
            final_pos_error=float(e_pos[-1]),
            final_rot_error=float(e_rot[-1]),
            min_clearance=min_clear,
            link_names=self.link_names,
            max_limit_violation=float(max(0.0, -margin.min())),
            min_limit_margin=float(margin.min()),
            max_velocity_ratio=ratio,
            solve_time=times,
            statuses={str(k): int(c) for k, c in zip(kinds, counts)},
            facts=self.facts,
        )
