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


def points_in_triangles(p, a, b, c, eps=1e-12):
    """For points ``p`` (k, 2) and triangles with corners ``a, b, c`` (T, 2): a (k, T) bool
    matrix, True where the point lies inside (either orientation)."""
    v0, v1 = b - a, c - a  # (T, 2)
    v2 = p[:, None, :] - a[None]  # (k, T, 2)
    den = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]  # (T,)
    safe = np.where(np.abs(den) > eps, den, np.inf)
    beta = (v2[..., 0] * v1[:, 1] - v1[:, 0] * v2[..., 1]) / safe
    gamma = (v0[:, 0] * v2[..., 1] - v2[..., 0] * v0[:, 1]) / safe
    return (beta > 0) & (gamma > 0) & (beta + gamma < 1)


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


def resolve_body_contacts(x, v, m, bodies, restitution=0.2, friction=0.3, margin=0.25):
    """Push boundary vertices of each body out of every other body; update ``x``, ``v`` in place.

    ``bodies``: list of dicts with ``idx`` (n_b,) global vertex indices, ``tris`` (T_b, 3)
    global triangle indices, ``boundary`` (B_b,) global boundary vertex indices and
    ``edges`` (E_b, 2) global boundary edges. Returns the number of contacts."""
    hits = 0
    boxes = [(x[b["idx"]].min(0), x[b["idx"]].max(0)) for b in bodies]
    for ia, A in enumerate(bodies):
        for ib, B in enumerate(bodies):
            if ia == ib:
                continue
            (alo, ahi), (blo, bhi) = boxes[ia], boxes[ib]
            if np.any(ahi < blo) or np.any(bhi < alo):
                continue  # bounding boxes apart
            cand = A["boundary"]
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
            q, j, u, dist = closest_points_on_segments(xa, x[e[:, 0]], x[e[:, 1]])
            nrm = (q - xa) / np.maximum(dist, 1e-12)[:, None]  # outward from B at the contact
            e0, e1 = e[j, 0], e[j, 1]
            # velocity of the contact point on B's edge and the effective masses
            w0, w1 = 1 - u, u
            vb = w0[:, None] * v[e0] + w1[:, None] * v[e1]
            ma = m[cand]
            mb = 1.0 / np.maximum(w0**2 / m[e0] + w1**2 / m[e1], 1e-300)
            share_a = mb / (ma + mb)
            # positions: split the correction by mass too, so heavy bodies move less
            corr = (dist + margin)[:, None] * nrm
            x[cand] += share_a[:, None] * corr
            # B's contact point moves by -(1 - share_a) corr: edge vertex i by w_i / Σw² of it
            back = ((1 - share_a) / np.maximum(w0**2 + w1**2, 1e-12))[:, None] * corr
            np.add.at(x, e0, -w0[:, None] * back)
            np.add.at(x, e1, -w1[:, None] * back)
            # impulse I on A's vertex and -I on B's contact point (Δv_i = -w_i I / m_i there),
            # sized so the relative velocity changes by dv: Δv_A = I / m_A = share_a dv
            dv = _respond(v[cand] - vb, nrm, restitution, friction)
            v[cand] += share_a[:, None] * dv
            impulse = (ma * share_a)[:, None] * dv
            np.add.at(v, e0, -(w0 / m[e0])[:, None] * impulse)
            np.add.at(v, e1, -(w1 / m[e1])[:, None] * impulse)
            hits += len(cand)
    return hits
