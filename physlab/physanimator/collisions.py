"""Contacts for PhysAnimator scenes (supp. Sec. 4.2, Fig. 7): bodies against the ground and
walls, and body against body.

Both are resolved by projection after each time step (the paper does not specify its collision
handling; this is physlab's choice): penetrating vertices are moved back to the closest
boundary point, the approaching normal velocity is reflected with a restitution coefficient
``e`` and the tangential velocity is reduced by Coulomb friction ``μ |Δv_n|``.

* half-planes ``n · x >= c`` (unit normal ``n`` pointing into the allowed region) model the
  ground and walls; in image coordinates (y down) the ground ``y <= y_g`` is ``n = (0, -1)``,
  ``c = -y_g``;
* body–body: a boundary vertex of body A lying inside a (deformed) triangle of body B is
  pushed to the closest point of B's boundary; the velocity change is shared with B's edge
  vertices in proportion to the masses (momentum is conserved).
"""
from __future__ import annotations

import numpy as np

__all__ = ["resolve_half_planes", "points_in_triangles", "closest_points_on_segments",
           "resolve_body_contacts"]


def _respond(v_rel, n, restitution, friction):
    """Velocity change (k, 2) that makes the relative velocity ``v_rel`` (k, 2) non-approaching
    along unit normals ``n`` (k, 2), with restitution and Coulomb friction."""
    vn = np.einsum("kd,kd->k", v_rel, n)
    approaching = vn < 0
    dvn = np.where(approaching, -(1 + restitution) * vn, 0.0)
    vt = v_rel - vn[:, None] * n
    speed_t = np.linalg.norm(vt, axis=1)
    cut = np.minimum(friction * dvn, speed_t)
    t_dir = vt / np.maximum(speed_t, 1e-12)[:, None]
    return dvn[:, None] * n - cut[:, None] * t_dir


def resolve_half_planes(x, v, planes, restitution=0.2, friction=0.3):
    """Project vertices ``x`` (n, 2) into every half-plane ``(n, c)``: ``n·x >= c``; update
    ``v`` in place. Returns the number of contacts."""
    hits = 0
    for normal, c in planes:
        normal = np.asarray(normal, dtype=float)
        pen = c - x @ normal
        idx = np.flatnonzero(pen > 0)
        if idx.size:
            hits += idx.size
            x[idx] += pen[idx, None] * normal
            nn = np.broadcast_to(normal, (idx.size, 2))
            v[idx] += _respond(v[idx], nn, restitution, friction)
    return hits


def points_in_triangles(p, a, b, c, eps=1e-9):
    """For points ``p`` (k, 2) and triangles with corners ``a, b, c`` (T, 2): a (k, T) bool
    matrix, True where the point lies inside or on the border (barycentric coordinates
    ``>= -eps``; either orientation; degenerate triangles contain nothing)."""
    v0, v1 = b - a, c - a  # (T, 2)
    v2 = p[:, None, :] - a[None]  # (k, T, 2)
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]  # (T,)
    safe = np.where(np.abs(den) > 1e-12, den, np.inf)
    beta = (v2[..., 0] * v1[:, 1] - v1[:, 0] * v2[..., 1]) / safe
    gamma = (v0[:, 0] * v2[..., 1] - v2[..., 0] * v0[:, 1]) / safe
    ok = np.isfinite(safe)[None, :]
    return ok & (beta >= -eps) & (gamma >= -eps) & (beta + gamma <= 1 + eps)


def closest_points_on_segments(p, s0, s1):
    """Closest point on any of the segments ``[s0, s1]`` (E, 2) to each ``p`` (k, 2).

    Returns ``(point (k, 2), segment index (k,), parameter u (k,) in [0, 1], distance (k,))``."""
    d = s1 - s0
    L2 = np.maximum(np.einsum("ed,ed->e", d, d), 1e-24)
    u = np.clip(np.einsum("ked,ed->ke", p[:, None, :] - s0[None], d) / L2, 0.0, 1.0)  # (k, E)
    q = s0[None] + u[..., None] * d[None]
    dist = np.linalg.norm(q - p[:, None, :], axis=2)
    j = np.argmin(dist, axis=1)
    k = np.arange(len(p))
    return q[k, j], j, u[k, j], dist[k, j]


def resolve_body_contacts(x, v, inv_m, bodies, restitution=0.2, friction=0.3, margin=0.25,
                          iterations=10, x_prev=None):
    """Push boundary vertices of each body out of every other body; update ``x``, ``v`` in place.

    ``inv_m`` (n,): inverse vertex masses, 0 for kinematic (pinned or rigged) vertices, which
    then never move. ``bodies``: list of dicts with ``idx`` (n_b,) global vertex indices,
    ``tris`` (T_b, 3) and ``edges`` (E_b, 2) global indices, ``boundary`` (B_b,) global
    boundary vertex indices.

    A penetrating vertex of A is sent back to the boundary edge of B it crossed during the
    step (from ``x_prev``, the positions before the step; so a fast vertex is not pushed out
    through B's far side), or to the closest boundary point when that is unknown; positions
    and impulses are split by inverse mass; the velocity response is
    iterated ``iterations`` times, averaging over the contacts that share a vertex of B, so
    that many contacts on one edge do not add up to an overshoot. Returns the number of contacts.
    """
    hits = 0
    boxes = [(x[b["idx"]].min(0), x[b["idx"]].max(0)) for b in bodies]
    for ia, A in enumerate(bodies):
        for ib, B in enumerate(bodies):
            if ia == ib:
                continue
            (alo, ahi), (blo, bhi) = boxes[ia], boxes[ib]
            if np.any(ahi < blo) or np.any(bhi < alo):
                continue  # bounding boxes apart
            cand = A["idx"]  # all vertices: a fast impact can fold the boundary inwards
            xa = x[cand]
            near = np.all((xa >= blo) & (xa <= bhi), axis=1)
            if not near.any():
                continue
            cand, xa = cand[near], xa[near]
            T = B["tris"]
            inside = points_in_triangles(xa, x[T[:, 0]], x[T[:, 1]], x[T[:, 2]]).any(axis=1)
            if not inside.any():
                continue
            cand, xa = cand[inside], xa[inside]
            e = B["edges"]
            s0, s1 = x[e[:, 0]], x[e[:, 1]]
            # closest boundary point among those against the motion relative to B
            d = s1 - s0
            L2 = np.maximum(np.einsum("ed,ed->e", d, d), 1e-24)
            uu = np.clip(np.einsum("ked,ed->ke", xa[:, None, :] - s0[None], d) / L2, 0.0, 1.0)
            qq = s0[None] + uu[..., None] * d[None]  # (k, E, 2)
            dd = np.linalg.norm(qq - xa[:, None, :], axis=2)
            k = np.arange(len(cand))
            j = np.argmin(dd, axis=1)  # default: the closest boundary point
            if x_prev is not None:  # better: the edge the vertex crossed on its way in
                p0 = x_prev[cand]
                r = xa - p0  # (k, 2) motion during the step
                cross = lambda a, b: a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
                den = cross(r[:, None, :], d[None])  # (k, E)
                ok = np.abs(den) > 1e-12
                sden = np.where(ok, den, 1.0)
                w = s0[None] - p0[:, None, :]
                tt, ue = cross(w, d[None]) / sden, cross(w, r[:, None, :]) / sden
                hit = ok & (tt >= 0) & (tt <= 1) & (ue >= 0) & (ue <= 1)
                first = np.argmin(np.where(hit, tt, np.inf), axis=1)
                j = np.where(hit.any(1), first, j)
            q, u, dist = qq[k, j], uu[k, j], dd[k, j]
            # outward normal: towards the exit point, or the edge's own outward normal when the
            # vertex sits on the edge (boundary edges run with the interior on their left)
            de = d[j] / np.sqrt(L2[j])[:, None]
            edge_out = np.stack([de[:, 1], -de[:, 0]], 1)
            nrm = np.where((dist > 1e-9)[:, None], (q - xa) / np.maximum(dist, 1e-12)[:, None], edge_out)
            e0, e1 = e[j, 0], e[j, 1]
            w0, w1 = 1 - u, u
            ia_ = inv_m[cand]
            ib_ = w0**2 * inv_m[e0] + w1**2 * inv_m[e1]  # inverse effective mass of B's point
            tot = ia_ + ib_
            movable = tot > 0
            share_a = np.where(movable, ia_ / np.where(movable, tot, 1.0), 0.0)
            # positions: A's vertex moves share_a of the way, B's contact point the rest
            corr = (dist + margin)[:, None] * nrm
            x[cand] += share_a[:, None] * corr
            wb = np.where(movable, (1 - share_a) / np.maximum(w0**2 + w1**2, 1e-12), 0.0)
            wb0 = np.where(inv_m[e0] > 0, w0 * wb, 0.0)
            wb1 = np.where(inv_m[e1] > 0, w1 * wb, 0.0)
            np.add.at(x, e0, -wb0[:, None] * corr)
            np.add.at(x, e1, -wb1[:, None] * corr)
            # velocities: impulse I = dv / (1/m_A + 1/m_B) on A, -I at B's contact point
            # contacts sharing a vertex of B each apply 1/count of their impulse per sweep
            # (Jacobi averaging; momentum is conserved exactly since A and B get ±I)
            count = np.bincount(np.concatenate([e0, e1]), minlength=len(v)).astype(float)
            share = 1.0 / np.maximum(count[e0], count[e1])
            for _ in range(iterations):
                vb = w0[:, None] * v[e0] + w1[:, None] * v[e1]
                dv = _respond(v[cand] - vb, nrm, restitution, friction)
                I = (share * np.where(movable, 1.0 / np.where(movable, tot, 1.0), 0.0))[:, None] * dv
                v[cand] += ia_[:, None] * I
                np.add.at(v, e0, -(w0 * inv_m[e0])[:, None] * I)
                np.add.at(v, e1, -(w1 * inv_m[e1])[:, None] * I)
            hits += len(cand)
    return hits


def max_penetration(animation, scene=None):
    """Deepest penetration (px) of any body into another in each stored frame.

    For every ordered pair of bodies (A, B) and frame, the vertices of A inside a triangle of
    B are found (:func:`points_in_triangles`) and their distance to B's boundary
    (:func:`closest_points_on_segments`) is the depth. ``animation`` is the
    :class:`~physlab.physanimator.Animation` of :func:`~physlab.physanimator.simulate`
    (``scene`` defaults to ``animation.scene``). Returns (F,) float, 0 where no vertex is
    inside another body; ``.max()`` is the deepest over the run."""
    scene = animation.scene if scene is None else scene
    bodies = scene.bodies
    if len(animation.x) != len(bodies):
        raise ValueError(f"the animation has {len(animation.x)} bodies, the scene "
                         f"{len(bodies)}: pass the scene that was simulated")
    F = len(animation.t)
    depth = np.zeros(F)
    for ia in range(len(bodies)):
        for ib in range(len(bodies)):
            if ia == ib:
                continue
            T, e = bodies[ib].mesh.tris, bodies[ib].mesh.boundary_edges()
            for k in range(F):                  # frames: few; vertices and triangles vectorised
                a, b = animation.x[ia][k], animation.x[ib][k]
                inside = points_in_triangles(a, b[T[:, 0]], b[T[:, 1]], b[T[:, 2]]).any(1)
                if inside.any():
                    d = closest_points_on_segments(a[inside], b[e[:, 0]], b[e[:, 1]])[3]
                    depth[k] = max(depth[k], float(d.max()))
    return depth
