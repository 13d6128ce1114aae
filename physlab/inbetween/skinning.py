"""Two classical skeleton deformers to compare with :mod:`physlab.inbetween.deform`.

Both move a 2D triangle mesh (rest vertices ``X`` (n, 2) in pixels, y down; triangles
``tris`` (T, 3)) so that it follows a skeleton going from a rest pose to a new pose.

**Linear blend skinning** (LBS; Magnenat-Thalmann et al. 1988) gives every bone ``b`` an
affine transform ``A_b`` (2, 3) (:func:`bone_transforms`) and every vertex a weight per
bone, and blends the transformed positions ::

    x_i = Σ_b w_ib A_b [X_i; 1]                                              # Eq. (LBS)

The weights here are *bounded biharmonic weights* (Jacobson et al. 2011, Eq. (1)–(3)) ::

    w_b = argmin_w ½ ∫ (Δw)² dA   s.t.  w = 1 on bone b's samples, 0 on the other bones',
                                        0 ≤ w ≤ 1,                            # Eq. (BBW)

each a quadratic program over the mesh's bilaplacian ``L M⁻¹ L`` (solved by libigl's
active-set method, :func:`igl.bbw`), rows normalised to sum to 1 afterwards (as libigl
does, the bound constraints keep them in [0, 1]). LBS is linear in the transforms, so it is
cheap and exact for rigid motions, but at a bent joint the blend of two rotations is not a
rotation: the inside of an elbow *collapses* (triangles shrink, degenerate, fold over) and
the outside loses area — the 2D face of the "candy-wrapper" artefact.

**As-rigid-as-possible** deformation (ARAP; Sorkine & Alexa 2007, Eq. (3)) instead pins the
handle vertices at their targets and minimises, over the positions ``x`` and one rotation
``R_t`` per triangle (libigl's ``ARAP_ENERGY_TYPE_ELEMENTS``, the 2D default) ::

    E(x, R) = Σ_t Σ_{(i,j) ∈ t} c_ij ‖(x_i − x_j) − R_t (X_i − X_j)‖²,        # Eq. (ARAP)

``c_ij`` the cotangent weights, which for a linear triangle equals ``Σ_t A_t ‖F_t − R_t‖²_F``
(``F_t`` the deformation gradient). The local–global solver alternates the best rotations
(polar decomposition per triangle) with one sparse linear solve whose matrix (the cotangent
Laplacian with the handles eliminated) is factored once. Local rigidity keeps triangle areas
close to rest where LBS collapses, at the price of an iterative solve (and no guarantee
against fold-overs: the handles alone steer it).

libigl's ARAP was checked to behave in 2D (``dim = 2``, tests): started from the rest shape
it finds a rigid motion of the handles (to 10⁻⁶ px in 300 iterations), its energy decreases
monotonically, and its result is a stationary point of Eq. (ARAP) computed independently.

References
----------
[BBW] A. Jacobson, I. Baran, J. Popović, O. Sorkine, "Bounded Biharmonic Weights for
    Real-Time Deformation", SIGGRAPH 2011.
[ARAP] O. Sorkine, M. Alexa, "As-Rigid-As-Possible Surface Modeling", SGP 2007.
[LBS] N. Magnenat-Thalmann, R. Laperrière, D. Thalmann, "Joint-dependent local deformations
    for hand animation and object grasping", Graphics Interface 1988.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .skeleton import MIN_BONE_LENGTH, Skeleton, check_compatible

__all__ = [
    "ARAP_MAX_ITER",
    "LimbExample",
    "arap_deform",
    "bbw_weights",
    "bending_limb_example",
    "bone_transforms",
    "flipped_triangles",
    "lbs_deform",
    "skeleton_deform",
    "triangle_area_ratios",
]

#: Default number of ARAP local–global iterations (libigl runs exactly this many).
ARAP_MAX_ITER = 100
#: Relative distance (× mesh size) below which two points count as coincident.
_REL_TOL = 1e-9


# ---------------------------------------------------------------------------------- checks
def _check_X_tris(X, tris):
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"X must have shape (n, 2), got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ValueError("X contains NaN or inf")
    tris = np.asarray(tris)
    if tris.ndim != 2 or tris.shape[1] != 3 or len(tris) == 0:
        raise ValueError(f"tris must have shape (T, 3) with T >= 1, got {tris.shape}")
    if not np.issubdtype(tris.dtype, np.integer):
        raise ValueError(f"tris must be an integer array, got dtype {tris.dtype}")
    if tris.min() < 0 or tris.max() >= len(X):
        raise ValueError(f"tris refer to vertices outside 0..{len(X) - 1} "
                         f"(min {tris.min()}, max {tris.max()})")
    return X, tris.astype(np.int64)


def _check_handle_vertices(handle_vertices, n, K=None, name="handle_vertices"):
    hv = np.asarray(handle_vertices)
    if hv.ndim != 1 or (K is not None and len(hv) != K):
        want = f"({K},)" if K is not None else "(k,)"
        raise ValueError(f"{name} must have shape {want}, got {hv.shape}"
                         + (" (one entry per handle of skeleton.handles(): joints, then bone "
                            "midpoints; -1 for handles that are not vertices)" if K else ""))
    if len(hv) and not np.issubdtype(hv.dtype, np.integer):
        raise ValueError(f"{name} must hold integer vertex indices, got dtype {hv.dtype}")
    hv = hv.astype(np.int64)
    bad = np.flatnonzero((hv < -1) | (hv >= n))
    if bad.size:
        k = int(bad[0])
        raise ValueError(f"{name}[{k}] = {hv[k]} is not a vertex index (the mesh has {n} "
                         f"vertices, valid 0..{n - 1}; use -1 for a handle that is not a vertex)")
    return hv


def _scale(X):
    return float(max(np.ptp(X, axis=0).max(), 1.0))


# ---------------------------------------------------------------------------------- transforms
def bone_transforms(skeleton_rest, skeleton_pose, stretch=True):
    """One affine transform per bone, mapping the rest bone onto the posed bone.

    For bone ``b = (p, c)`` with rest vector ``d = X_c − X_p`` and posed vector
    ``d' = x_c − x_p``: ``A_b = R S`` where ``S = I + (|d'|/|d| − 1) u uᵀ`` stretches along
    the rest direction ``u = d/|d|`` (identity if ``stretch`` is False) and ``R`` is the
    rotation taking ``u`` to ``d'/|d'|``; the translation ``t_b = x_p − A_b X_p`` keeps the
    parent joint on its posed position. So ``A_b`` maps ``X_p ↦ x_p`` and, with ``stretch``,
    ``X_c ↦ x_c``.

    A bone of zero length in either pose (e.g. AnimatedDrawings' root→hip) has no direction:
    it takes its parent bone's linear part (the identity under the root) with the
    translation that maps its parent joint ``X_p ↦ x_p`` — the parent bone's transform itself
    when ``stretch`` is on, the root translation under the root.

    Parameters
    ----------
    skeleton_rest, skeleton_pose : Skeleton, same topology (:func:`check_compatible`), pixels.
    stretch : bool, scale along each bone to its posed length (else rotation + translation).

    Returns
    -------
    (B, 2, 3) float64 ``[A_b | t_b]``, bones in ``skeleton_rest.bones`` order, so that
    ``A[b] @ [X; 1]`` is the moved point.
    """
    check_compatible(skeleton_rest, skeleton_pose, ("skeleton_rest", "skeleton_pose"))
    P0, P1 = skeleton_rest.xy, skeleton_pose.xy
    parents = skeleton_rest.parents
    d0, d1 = skeleton_rest.bone_vectors(), skeleton_pose.bone_vectors()  # (J, 2)
    l0, l1 = np.linalg.norm(d0, axis=1), np.linalg.norm(d1, axis=1)
    ok = (l0 > MIN_BONE_LENGTH) & (l1 > MIN_BONE_LENGTH) & (parents >= 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(ok[:, None], d0 / l0[:, None], 0.0)  # (J, 2) rest unit direction
        c = np.where(ok, np.einsum("jd,jd->j", d0, d1) / (l0 * l1), 1.0)
        s = np.where(ok, (d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]) / (l0 * l1), 0.0)
        k = np.where(ok, l1 / l0, 1.0) if stretch else np.ones(len(parents))
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (J, 2, 2)
    S = np.eye(2) + (k - 1.0)[:, None, None] * np.einsum("ja,jb->jab", u, u)
    A = R @ S  # (J, 2, 2) linear part of the bone into each joint
    # zero-length bones inherit their parent bone's linear part (identity under the root)
    for j in skeleton_rest.order:
        p = parents[j]
        if p >= 0 and not ok[j]:
            A[j] = A[p] if parents[p] >= 0 else np.eye(2)
    t = np.zeros((len(parents), 2))
    child = np.flatnonzero(parents >= 0)
    t[child] = P1[parents[child]] - np.einsum("jab,jb->ja", A[child], P0[parents[child]])
    bones = skeleton_rest.bones
    return np.concatenate([A[bones[:, 1]], t[bones[:, 1], :, None]], axis=2)  # (B, 2, 3)


def lbs_deform(X, weights, transforms):
    """Linear blend skinning, Eq. (LBS): ``x_i = Σ_b w_ib A_b [X_i; 1]``.

    Evaluated in displacement form, ``x_i = X_i + Σ_b w_ib (A_b − [I | 0]) [X_i; 1]``, which
    is the same for weights that sum to 1 and returns ``X`` bit for bit when every
    transform is the identity.

    Parameters
    ----------
    X : (n, 2) float rest positions (pixels).
    weights : (n, B) float skinning weights, rows summing to 1 (:func:`bbw_weights`).
    transforms : (B, 2, 3) float affine bone transforms (:func:`bone_transforms`).

    Returns
    -------
    (n, 2) float64 deformed positions.
    """
    X = np.asarray(X, dtype=np.float64)
    W = np.asarray(weights, dtype=np.float64)
    A = np.asarray(transforms, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 2:
        raise ValueError(f"X must have shape (n, 2), got {X.shape}")
    if A.ndim != 3 or A.shape[1:] != (2, 3):
        raise ValueError(f"transforms must have shape (B, 2, 3), got {A.shape}")
    if W.shape != (len(X), len(A)):
        raise ValueError(f"weights must have shape (n, B) = ({len(X)}, {len(A)}), got {W.shape}")
    if len(X) and np.abs(W.sum(1) - 1.0).max() > 1e-6:
        i = int(np.argmax(np.abs(W.sum(1) - 1.0)))
        raise ValueError(f"skinning weights must sum to 1 per vertex (row {i} sums to "
                         f"{W[i].sum():.6g}); normalise them: W / W.sum(1, keepdims=True)")
    Xh = np.concatenate([X, np.ones((len(X), 1))], axis=1)  # (n, 3)
    D = A - np.eye(2, 3)  # (B, 2, 3) transform minus identity
    blended = np.einsum("nb,bij->nij", W, D)  # (n, 2, 3) per-vertex blended displacement map
    return X + np.einsum("nij,nj->ni", blended, Xh)  # Eq. (LBS)


# ---------------------------------------------------------------------------------- weights
def _live_bones(skeleton):
    """(B,) bool: bones (``skeleton.bones`` order) longer than MIN_BONE_LENGTH."""
    return skeleton.bone_lengths()[skeleton.bones[:, 1]] > MIN_BONE_LENGTH


def _handle_rows(skeleton, live, tol):
    """(J + B, B) boundary values of every handle: joints split evenly among the live bones
    that touch them (joints at the same place are merged, so a zero-length bone's two ends
    share their neighbours), bone midpoints one-hot (zero-length: as their joint)."""
    J, bones = len(skeleton), skeleton.bones
    B = len(bones)
    inc = np.zeros((J, B))  # joint-bone incidence of live bones
    inc[bones[live, 0], np.flatnonzero(live)] = 1.0
    inc[bones[live, 1], np.flatnonzero(live)] = 1.0
    same = np.linalg.norm(skeleton.xy[:, None] - skeleton.xy[None], axis=-1) <= tol  # (J, J)
    joint_rows = ((same.astype(float) @ inc) > 0).astype(float)
    mid_rows = np.where(live[:, None], np.eye(B), joint_rows[bones[:, 1]])
    rows = np.concatenate([joint_rows, mid_rows])
    sums = rows.sum(1, keepdims=True)
    return np.divide(rows, sums, out=np.zeros_like(rows), where=sums > 0)


def bbw_weights(X, tris, skeleton, handle_vertices, max_iter=100):
    """Bounded biharmonic skinning weights, one column per bone, Eq. (BBW) [BBW].

    Boundary conditions (which vertices are fixed at which weights):

    * every mesh vertex lying *on* a bone segment (libigl's
      :func:`igl.boundary_conditions` with the bones as bone edges, tolerance 3·10⁻⁴ px) —
      interior points of bone ``b`` get ``w_b = 1``, a joint shared by ``k`` bones gets
      ``1/k`` for each of them (the elbow is half upper arm, half forearm; a leaf joint such
      as the hand belongs to its one bone; the root to all its child bones);
    * every handle vertex ``handle_vertices[h] >= 0`` by the same rule applied to its handle
      (this matters when a handle's vertex does not sit exactly on the skeleton): a bone
      midpoint gets its bone, a joint is split evenly among the bones touching it.

    Zero-length bones (AnimatedDrawings' root→hip) are left out of the solve and get weight
    0 everywhere (their transform copies their parent's, :func:`bone_transforms`); their
    end joints, which coincide, share the bones that touch either of them.

    Parameters
    ----------
    X : (n, 2) float rest positions (pixels).
    tris : (T, 3) int triangles.
    skeleton : Skeleton in the same pixel coordinates (rest pose).
    handle_vertices : (J + B,) int mesh vertex of each handle of ``skeleton.handles()``
        (joints then bone midpoints), -1 for a handle that is not a vertex (ignored).
    max_iter : int, active-set iterations per weight (libigl default 100).

    Returns
    -------
    (n, B) float64 weights in [0, 1] with rows summing to 1, bones in ``skeleton.bones``
    order.

    Raises
    ------
    ValueError for bad shapes or indices, a skeleton without a bone of positive length, a
    bone with no mesh vertex of its own (give every bone midpoint a vertex:
    ``triangulate_polygon(..., points=skeleton.handles())``), or a connected piece of the
    mesh with no constrained vertex.
    """
    import igl

    X, tris = _check_X_tris(X, tris)
    if not isinstance(skeleton, Skeleton):
        raise TypeError(f"skeleton must be a physlab.inbetween.Skeleton, got "
                        f"{type(skeleton).__name__}")
    bones = skeleton.bones
    B, J = len(bones), len(skeleton)
    hv = _check_handle_vertices(handle_vertices, len(X), J + B)
    live = _live_bones(skeleton)
    if not live.any():
        raise ValueError("the skeleton has no bone of positive length; skinning needs at least "
                         "one bone")
    tol = _REL_TOL * _scale(X)
    L = int(live.sum())
    # (1) vertices on the (live) bones: libigl reads 3D points, so pad with z = 0
    try:
        b_geo, bc_geo = igl.boundary_conditions(
            np.c_[X, np.zeros(len(X))], tris, np.c_[skeleton.xy, np.zeros(J)],
            np.zeros(0, dtype=np.int64), np.ascontiguousarray(bones[live]))
    except RuntimeError:  # a bone without a vertex of its own: rely on the handles alone
        b_geo, bc_geo = np.zeros(0, dtype=np.int64), np.zeros((0, L))
    # (2) the handle vertices override, by the same rule at their handles
    rows = _handle_rows(skeleton, live, tol)[:, live]  # (J + B, L)
    use = hv >= 0
    b_h, bc_h = hv[use], rows[use]
    # merge: handle rows win; several handles on one vertex are averaged
    vb = np.unique(np.concatenate([b_geo, b_h]))
    bc = np.zeros((len(vb), L))
    geo_only = ~np.isin(b_geo, b_h)
    bc[np.searchsorted(vb, b_geo[geo_only])] = bc_geo[geo_only]
    if len(b_h):
        pos = np.searchsorted(vb, b_h)
        acc = np.zeros((len(vb), L))
        cnt = np.zeros(len(vb))
        np.add.at(acc, pos, bc_h)
        np.add.at(cnt, pos, 1.0)
        hit = cnt > 0
        bc[hit] = acc[hit] / cnt[hit, None]
    names = skeleton.names
    lonely = np.flatnonzero(bc.max(0, initial=0.0) < 1.0 - 1e-9) if len(vb) else np.arange(L)
    if lonely.size:
        b0 = bones[np.flatnonzero(live)[lonely[0]]]
        raise ValueError(f"{lonely.size} bone(s) have no mesh vertex of their own, the first is "
                         f"{names[b0[0]]}→{names[b0[1]]}: put a vertex at every bone midpoint "
                         "(triangulate_polygon(..., points=skeleton.handles())) and pass it in "
                         "handle_vertices")
    _check_components_constrained(len(X), tris, vb)
    W_live = igl.bbw(X, tris, vb.astype(np.int64), bc, partition_unity=False,
                     max_iter=int(max_iter))  # Eq. (BBW), unnormalised
    W_live = np.clip(W_live, 0.0, 1.0)
    W_live /= W_live.sum(1, keepdims=True)  # as igl::normalize_row_sums
    W = np.zeros((len(X), B))
    W[:, live] = W_live
    return W


def _check_components_constrained(n, tris, b):
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    G = sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, label = connected_components(G, directed=False)
    used = np.zeros(n, bool)
    used[tris.ravel()] = True
    free = np.setdiff1d(np.unique(label[used]), label[b])
    if free.size:
        m = int(np.sum(np.isin(label, free) & used))
        raise ValueError(f"{free.size} connected piece(s) of the mesh ({m} vertices) contain no "
                         "handle or bone vertex, so their weights are undefined; mesh each "
                         "body with the skeleton handles inside it, or drop those triangles")


# ---------------------------------------------------------------------------------- ARAP
def arap_deform(X, tris, handle_vertices, targets, x0=None, max_iter=ARAP_MAX_ITER):
    """As-rigid-as-possible deformation with the handle vertices pinned, Eq. (ARAP) [ARAP].

    libigl's local–global solver (:func:`igl.arap_precomputation` with ``dim = 2``,
    :func:`igl.arap_solve`; per-triangle rotations, ``ARAP_ENERGY_TYPE_ELEMENTS``), run for
    exactly ``max_iter`` iterations from ``x0``. The energy decreases monotonically; a
    rigid motion of the handles is reproduced exactly once converged.

    Parameters
    ----------
    X : (n, 2) float rest positions (pixels).
    tris : (T, 3) int triangles.
    handle_vertices : (k,) int vertices to pin (k >= 1); entries -1 are ignored, like
        handles that are not vertices in :func:`bbw_weights`.
    targets : (k, 2) float their target positions (pixels). A vertex listed twice must have
        the same target twice.
    x0 : (n, 2) float initial guess, default ``X`` (rest). A skinned pose (LBS) or any guess
        with roughly the right rotations converges in far fewer iterations.
    max_iter : int >= 1, local–global iterations.

    Returns
    -------
    (n, 2) float64 positions; ``x[handle_vertices] == targets`` exactly.
    """
    import igl

    X, tris = _check_X_tris(X, tris)
    hv = _check_handle_vertices(handle_vertices, len(X))
    tg = np.asarray(targets, dtype=np.float64)
    if tg.shape != (len(hv), 2):
        raise ValueError(f"targets must have shape ({len(hv)}, 2) (one per handle vertex), "
                         f"got {tg.shape}")
    if not np.all(np.isfinite(tg)):
        raise ValueError("targets contain NaN or inf")
    if int(max_iter) < 1:
        raise ValueError(f"max_iter must be >= 1, got {max_iter}")
    keep = hv >= 0
    hv, tg = hv[keep], tg[keep]
    if len(hv) == 0:
        raise ValueError("arap_deform needs at least one handle vertex (all entries are -1)")
    b, first, inverse = np.unique(hv, return_index=True, return_inverse=True)
    bc = tg[first]
    clash = np.linalg.norm(tg - bc[inverse.ravel()], axis=1) > _REL_TOL * _scale(X)
    if clash.any():
        v = int(hv[np.flatnonzero(clash)[0]])
        raise ValueError(f"vertex {v} is given two different targets; a handle vertex can only "
                         "go to one place (merge coincident handles first)")
    if x0 is None:
        x0 = X
    x0 = np.array(x0, dtype=np.float64)
    if x0.shape != X.shape:
        raise ValueError(f"x0 must have the shape of X {X.shape}, got {x0.shape}")
    x0[b] = bc
    data = igl.ARAPData()
    data.energy = igl.ARAPEnergyType.ARAP_ENERGY_TYPE_ELEMENTS  # the 2D default, made explicit
    data.max_iter = int(max_iter)
    igl.arap_precomputation(X, tris, 2, b.astype(np.int32), data)
    x = igl.arap_solve(bc, data, x0)  # Eq. (ARAP), local–global
    x[b] = bc  # exact (the solver already keeps them; guard against round-off)
    return x


# ---------------------------------------------------------------------------------- diagnostics
def triangle_area_ratios(X, x, tris):
    """(T,) signed area of each triangle in ``x`` divided by its area in ``X``.

    1 for a rigid motion; ≤ 0 for a triangle that collapsed or folded over
    (Eq. (A) of :mod:`physlab.mesh`).
    """
    from ..mesh import triangle_areas

    X, tris = _check_X_tris(X, tris)
    x = np.asarray(x, dtype=np.float64)
    if x.shape != X.shape:
        raise ValueError(f"x must have the shape of X {X.shape}, got {x.shape}")
    return triangle_areas(x, tris) / triangle_areas(X, tris)


def flipped_triangles(X, x, tris, rtol=1e-6):
    """Indices of triangles that fold over or collapse going from ``X`` to ``x``.

    A triangle is reported when its signed area changes sign or shrinks to at most ``rtol``
    times its rest area (:func:`triangle_area_ratios` ``<= rtol``); works for either rest
    orientation.

    Parameters
    ----------
    X, x : (n, 2) float rest and deformed positions.
    tris : (T, 3) int triangles.
    rtol : float, relative area below which a triangle counts as degenerate.

    Returns
    -------
    (k,) int64 sorted triangle indices.
    """
    return np.flatnonzero(triangle_area_ratios(X, x, tris) <= rtol).astype(np.int64)


# ---------------------------------------------------------------------------------- driver
def skeleton_deform(X, tris, skeleton_rest, skeleton_pose, handle_vertices, method="lbs",
                    weights=None, stretch=True, max_iter=ARAP_MAX_ITER):
    """Deform a mesh from a rest skeleton to a posed one with LBS or ARAP.

    * ``method="lbs"``: :func:`lbs_deform` with :func:`bone_transforms` and ``weights``
      (default :func:`bbw_weights`).
    * ``method="arap"``: :func:`arap_deform` with every handle vertex pinned at its posed
      handle, ``skeleton_pose.handles()[h]`` (handles that are not vertices are ignored).
      It starts from the LBS pose when ``weights`` are given, otherwise from *rigid
      skinning* (each vertex moved by the transform of its nearest bone) — cheap, and it
      has the right rotations, which ARAP's local step needs.

    Parameters
    ----------
    X : (n, 2) float rest positions (pixels); tris : (T, 3) int.
    skeleton_rest, skeleton_pose : Skeleton, same topology; ``skeleton_rest`` in the
        coordinates of ``X``.
    handle_vertices : (J + B,) int vertex of each handle of ``skeleton_rest.handles()``, -1
        for none (e.g. ``Template.handle_vertices``).
    method : "lbs" or "arap".
    weights : (n, B) float or None, skinning weights (LBS, and ARAP's starting guess).
    stretch : bool, bone transforms stretch with the bones (:func:`bone_transforms`).
    max_iter : int, ARAP iterations.

    Returns
    -------
    (n, 2) float64 deformed positions (pixels).
    """
    X, tris = _check_X_tris(X, tris)
    check_compatible(skeleton_rest, skeleton_pose, ("skeleton_rest", "skeleton_pose"))
    K = len(skeleton_rest) + len(skeleton_rest.bones)
    hv = _check_handle_vertices(handle_vertices, len(X), K)
    if method not in ("lbs", "arap"):
        raise ValueError(f"method must be 'lbs' or 'arap', got {method!r}")
    A = bone_transforms(skeleton_rest, skeleton_pose, stretch=stretch)
    if method == "lbs":
        if weights is None:
            weights = bbw_weights(X, tris, skeleton_rest, hv)
        return lbs_deform(X, weights, A)
    if weights is not None:
        x0 = lbs_deform(X, weights, A)
    else:
        x0 = lbs_deform(X, _nearest_bone_weights(X, skeleton_rest), A)
    return arap_deform(X, tris, hv, skeleton_pose.handles(), x0=x0, max_iter=max_iter)


def _nearest_bone_weights(X, skeleton):
    """(n, B) one-hot weights of each point's nearest live bone segment (rigid skinning)."""
    bones = skeleton.bones
    live = _live_bones(skeleton)
    a, c = skeleton.xy[bones[:, 0]], skeleton.xy[bones[:, 1]]  # (B, 2)
    d = c - a
    L2 = np.maximum(np.einsum("bd,bd->b", d, d), MIN_BONE_LENGTH**2)
    t = np.clip(np.einsum("nbd,bd->nb", X[:, None] - a[None], d) / L2, 0.0, 1.0)  # (n, B)
    dist = np.linalg.norm(X[:, None] - (a[None] + t[..., None] * d[None]), axis=-1)
    dist[:, ~live] = np.inf
    W = np.zeros((len(X), len(bones)))
    W[np.arange(len(X)), np.argmin(dist, axis=1)] = 1.0
    return W


# ---------------------------------------------------------------------------------- example
@dataclass(frozen=True, eq=False)
class LimbExample:
    """A 2D arm bent at the elbow, deformed by each method (:func:`bending_limb_example`).

    Attributes
    ----------
    X : (n, 2) float64 rest vertices (pixels, y down); tris : (T, 3) int64.
    skeleton_rest, skeleton_pose : Skeleton with joints shoulder → elbow → hand.
    handle_vertices : (5,) int64 vertices of the 3 joints and 2 bone midpoints.
    weights : (n, 2) float64 bounded biharmonic weights (upper arm, forearm).
    results : dict method name → (n, 2) deformed vertices ("lbs", "arap"), empty when the
        example was built with ``deform=False``.
    elbow_tris : (k,) int64 triangles within one arm width of the elbow.
    """

    X: np.ndarray
    tris: np.ndarray
    skeleton_rest: Skeleton
    skeleton_pose: Skeleton
    handle_vertices: np.ndarray
    weights: np.ndarray
    results: dict = field(default_factory=dict)
    elbow_tris: np.ndarray = None

    def area_ratios(self, method):
        """(T,) deformed / rest signed triangle areas of ``results[method]``."""
        return triangle_area_ratios(self.X, self.results[method], self.tris)


def bending_limb_example(angle_deg=120.0, length=240.0, width=48.0, max_area=None,
                         origin=(40.0, 120.0), deform=True, max_iter=ARAP_MAX_ITER):
    """A horizontal arm (rectangle) with a shoulder–elbow–hand skeleton, bent at the elbow.

    The arm spans ``length × width`` px from ``origin`` (its shoulder end, mid-height),
    meshed by :func:`physlab.mesh.triangulate_polygon` (min angle 25°) with the five
    handles (3 joints, 2 bone midpoints) inserted as vertices. The posed skeleton turns the
    forearm by ``angle_deg`` about the elbow (positive: the hand swings up on screen).

    Parameters
    ----------
    angle_deg : float, elbow bend in degrees.
    length, width : float > 0, arm size in pixels (the elbow is at half the length).
    max_area : float px² or None: ``width² / 40`` (≈ 350 vertices for the defaults).
    origin : (2,) float, shoulder position in pixels.
    deform : bool, also compute the weights' LBS and the ARAP results.
    max_iter : int, ARAP iterations.

    Returns
    -------
    LimbExample.
    """
    from ..mesh import triangulate_polygon, vertex_indices

    if not (length > 0 and width > 0):
        raise ValueError(f"length and width must be > 0 px, got {length} x {width}")
    ox, oy = (float(v) for v in origin)
    h = 0.5 * width
    poly = np.array([[ox, oy - h], [ox + length, oy - h], [ox + length, oy + h], [ox, oy + h]])
    names, parents = ("shoulder", "elbow", "hand"), np.array([-1, 0, 1])
    # joints sit a little inside the ends so that they are interior vertices
    inset = min(0.1 * length, 0.5 * h)
    rest = Skeleton(names, parents, [[ox + inset, oy], [ox + 0.5 * length, oy],
                                     [ox + length - inset, oy]])
    th = np.radians(angle_deg)
    elbow = rest.xy[1]
    rot = np.array([[np.cos(th), np.sin(th)], [-np.sin(th), np.cos(th)]])  # up on screen
    pose = rest.with_xy(np.stack([rest.xy[0], elbow, elbow + rot @ (rest.xy[2] - elbow)]))
    if max_area is None:
        max_area = width**2 / 40.0
    mesh = triangulate_polygon(poly, max_area=max_area, min_angle=25.0, points=rest.handles())
    X, tris = np.array(mesh.X), np.array(mesh.tris)
    hv = vertex_indices(mesh, rest.handles())
    W = bbw_weights(X, tris, rest, hv)
    centroid = X[tris].mean(axis=1)
    elbow_tris = np.flatnonzero(np.linalg.norm(centroid - elbow, axis=1) < width)
    results = {}
    if deform:
        results["lbs"] = skeleton_deform(X, tris, rest, pose, hv, "lbs", weights=W)
        results["arap"] = skeleton_deform(X, tris, rest, pose, hv, "arap", weights=W,
                                          max_iter=max_iter)
    return LimbExample(X, tris, rest, pose, hv, W, results, elbow_tris)
