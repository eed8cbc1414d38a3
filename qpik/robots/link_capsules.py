r"""One capsule per link of a loaded model, fitted around the link's geoms: :func:`link_capsules`.

Every body belongs to the link of the last arm joint above it; a link's capsule is the
smallest one containing its colliding geoms (all of its geoms when none collides), each geom
given as balls whose convex hull contains it (:func:`geom_balls`: mesh vertices, the corners of
a box or of an ellipsoid's bounding box, a cylinder's rims as polygons widened by their chord
error, a sphere or capsule's centres with its radius), fitted by
:func:`qpik.robots.capsule_fit.fit_capsule`. Capsules are in link frame *k* (the joint frame),
metres, at the chain's reference configuration. A fit is kept on disk beside the compiled code
(:func:`fitted`), so that loading the same model again, in any process, does not fit it again.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
from typing import TYPE_CHECKING

import numpy as np

from qpik.core.errors import InputError
from qpik.robots.body_tree import BodyTree
from qpik.robots.chain import SerialChain
from qpik.robots.robot import LinkCapsule

if TYPE_CHECKING:
    import mujoco


CIRCLE = 32  # points per rim of a cylinder (its capsule is widened by the chord error)


def link_capsules(
    model: mujoco.MjModel, tree: BodyTree, arm: list[int], chain: SerialChain, placement: np.ndarray
) -> tuple[LinkCapsule, ...]:
    """One capsule per link with geoms: the smallest containing its collision geoms (else all), in link frame k.

    ``arm``: every chain joint (link k is moved by chain joint k); ``tree`` at the chain's reference configuration;
    ``placement``: the base frame in the model's world frame (4, 4).
    """
    owner = {}  # body -> link index (1..n) of the arm joint that moves it last
    joint_body = [int(model.jnt_bodyid[j]) for j in arm]

    def assign(body: int, link: int) -> None:
        if body in joint_body:
            link = max(k + 1 for k, b in enumerate(joint_body) if b == body)
        owner[body] = link
        for c in tree.children[body]:
            assign(c, link)

    assign(0, 0)
    q_ref = np.array([-j.offset for j in chain.joints if j.mimic is None])
    frames = placement @ chain.frames(q_ref)  # link frames at the reference configuration (model's world)
    geoms: dict[int, list[int]] = {}
    for g in range(model.ngeom):
        link = owner[int(model.geom_bodyid[g])]
        if link:
            geoms.setdefault(link, []).append(g)
    balls: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for link, gs in geoms.items():
        colliding = [g for g in gs if model.geom_contype[g] or model.geom_conaffinity[g]]
        for g in colliding or gs:  # a link whose geoms all skip contacts (visual only): all of them
            balls.setdefault(link, []).append(geom_balls(model, tree, g))
    caps = []
    for link in sorted(balls):
        to_link = np.linalg.inv(frames[link])
        centres = np.concatenate([c for c, _ in balls[link]]) @ to_link[:3, :3].T + to_link[:3, 3]
        radii = np.concatenate([r for _, r in balls[link]])
        a, b, R = fitted(centres, radii)
        caps.append(LinkCapsule(link, a, b, R))
    return tuple(caps)


def fitted(centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`qpik.robots.capsule_fit.fit_capsule` of the balls (centres (N, 3), radii (N,), m), kept in the cache
    folder (:func:`qpik.native.build.cache_dir`) under a hash of the balls, the fit's settings and SciPy's version:
    a later call with the same balls reads the same numbers back. Where the folder cannot be written the fit is
    only not kept."""
    import scipy

    from qpik.native.build import cache_dir, keep
    from qpik.robots import capsule_fit  # SciPy's optimisers: only for a model file

    centres, radii = np.ascontiguousarray(centres, float), np.ascontiguousarray(radii, float)
    settings = f"{capsule_fit.DIRECTIONS} {capsule_fit.REFINED} {scipy.__version__} {centres.shape}".encode()
    key = hashlib.sha256(settings + centres.tobytes() + radii.tobytes()).hexdigest()[:40]
    path = cache_dir() / "capsules" / f"{key}.npz"
    try:
        with np.load(path) as kept:
            return kept["a"], kept["b"], float(kept["R"])
    except (OSError, ValueError, KeyError):  # not kept yet, or unreadable: fit again
        pass
    a, b, R = capsule_fit.fit_capsule(centres, radii)
    buffer = io.BytesIO()
    np.savez(buffer, a=a, b=b, R=R)
    with contextlib.suppress(OSError):  # a folder that cannot be written only leaves the fit unkept
        keep(path, buffer.getvalue())
    return a, b, R


def geom_balls(model: mujoco.MjModel, tree: BodyTree, g: int) -> tuple[np.ndarray, np.ndarray]:
    """Balls (world centres (N, 3), radii (N,)) whose convex hull contains geom g at the reference configuration."""
    import mujoco

    T = np.eye(4)
    T[:3, :3] = tree.data.geom_xmat[g].reshape(3, 3)
    T[:3, 3] = tree.data.geom_xpos[g]
    size = model.geom_size[g]
    kind = int(model.geom_type[g])
    G = mujoco.mjtGeom
    if kind == G.mjGEOM_MESH:
        m = int(model.geom_dataid[g])
        a, n = model.mesh_vertadr[m], model.mesh_vertnum[m]
        local, radius = model.mesh_vert[a : a + n].astype(float), 0.0
    elif kind == G.mjGEOM_SPHERE:
        local, radius = np.zeros((1, 3)), size[0]
    elif kind == G.mjGEOM_CAPSULE:
        local, radius = np.array([[0, 0, -size[1]], [0, 0, size[1]]]), size[0]
    elif kind == G.mjGEOM_BOX:
        local, radius = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size, 0.0
    elif kind == G.mjGEOM_CYLINDER:
        t = np.linspace(0, 2 * np.pi, CIRCLE, endpoint=False)
        rim = np.stack([np.cos(t), np.sin(t)], axis=1) * size[0] / np.cos(np.pi / CIRCLE)  # polygon around the rim
        local = np.concatenate([np.c_[rim, np.full(CIRCLE, z)] for z in (-size[1], size[1])])
        radius = 0.0
    elif kind == G.mjGEOM_ELLIPSOID:  # by its bounding box (contains it; not the smallest)
        local, radius = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * size, 0.0
    else:
        raise InputError(
            f"geom {model.geom(g).name or g!r}: type {G(kind).name[7:].lower()} cannot be fitted by a capsule"
        )
    centres = local @ T[:3, :3].T + T[:3, 3]
    return centres, np.full(len(centres), float(radius))
