"""Occlusion-aware layered templates (Brodt & Bessmeltsev 2024, Secs. 3, 4.1–4.4, 5.1).

A drawing whose limb crosses the body cannot be deformed as one sheet: under the skeletal
motion the deformation field is only piecewise smooth (Fig. 2d), and a single-layer template
tears. The paper lifts the drawing onto a *multi-sheet* domain (Fig. 5): inside every
occlusion region the template has two layers, sewn to the rest of the drawing along parts of
the region's outline, and the skeletal deformation of that domain is smooth again.

Inputs per keyframe (Sec. 4)
----------------------------
* :class:`Occlusion` — one occlusion region: a mask (or polygon) and its **T-junctions**,
  the points where one part's outline ends against the occluder's. The paper predicts masks
  with a DINOv2 U-Net (weights unavailable here); :func:`suggest_occlusions` is the honest
  CPU substitute — the 2D overlap of non-adjacent limbs' capsules, a suggestion the user
  accepts or edits (``predictor=`` is the seam for a learned one; ``widths=`` from
  :func:`bone_widths` of a drawing with free limbs gives each bone its drawn width instead of
  one capsule radius); with ``t_junctions=True``
  its regions carry :func:`suggest_t_junctions` (where the occluder's capsule outline meets the
  other outlines on the region's boundary), a CPU substitute for the user's clicks. With
  ``extent="contact"`` a limb's region grows to its whole contact with the body
  (:func:`limb_contact`: along the limb's axis, where the drawing is wider than the limb; cut
  across the limb where it leaves the body's outline), its T-junctions at that cut's corners.
* Joint depths near the regions (:attr:`Skeleton.depth`, smaller = nearer): they decide
  which layer is in front after the topology is found (Sec. 5.1).
* Where more than two parts overlap (a forearm in front of the torso in front of the other
  arm, Fig. 9), the paper asks for "occlusion masks, one per layer, sorted by depth" (Sec. 4):
  regions may overlap, each adds one layer over its area, and in an overlap the region listed
  first hides the nearer part (:func:`~physlab.inbetween.characters.
  character_layered_occlusions` gives such masks for the procedural character).

Building the template (:func:`build_layered_template`)
------------------------------------------------------
1. **Mask refinement** (Sec. 4.1): each region's outline (Douglas–Peucker, ε = 2 px) is
   deformed so that it passes through its T-junctions — the triangulated region is deformed
   with the symmetric Dirichlet energy (Eq. 2's ``E_d``) pulling the outline vertex nearest
   each T-junction onto it and fixing outline vertices far from every T-junction
   (:func:`refine_through_t_junctions`).
2. **Base mesh** (Sec. 4.2): a conforming Delaunay triangulation of the foreground with the
   region outlines as constrained edges (Triangle, minimum angle 20°), so every triangle is
   inside or outside each region; handles (joints and bone midpoints) are vertices.
   Overlapping outlines cross (Triangle inserts the crossings), so the overlap of two regions
   is meshed as its own piece with a constrained outline.
3. **Pockets** (Sec. 4.2, :func:`sew_pockets`): every region's triangles are duplicated as a
   second layer sewn to the base mesh along the whole outline. Handles inside a region go to
   one layer: nearer handles (by joint depth) to layer A, farther ones to layer B (the paper
   inserts them into an "arbitrary" layer; with limbs of both depths inside one region an
   arbitrary choice can put both into one layer, which no cut can fix).
   **Nested pockets** (more than two layers): every pocket covers its whole region, so where
   ``m`` regions overlap there are ``m + 1`` layers — the base and one pocket per region; a
   region's outline running inside another region is sewn to the base layer there, and the
   other region's pocket runs across it. The layers of an overlap are stacked in the order the
   occlusions are listed (base, then the pockets, front to back); the distinct joint depths
   of the handles in the overlapping regions, clustered into ``m + 1`` groups, put every
   handle there on its layer, and each region's own (non-overlapping) part splits its handles
   as above. Fewer distinct depths than layers, or a listed order the handles' depths
   contradict, raise a ValueError.
4. **Switching rule and topology** (Secs. 4.3–4.4, Eq. 2, Algorithm 1): every outline edge
   ``i`` gets ``b_i`` — which layer (A: 0, B: 1) stays attached to the outside there; the
   other layer is *incised* along it (vertex re-indexing, :func:`incise`). ``b`` may switch
   only at T-junctions (where it must) and at most at one *cusp* elsewhere, so a region with
   ``k`` T-junctions and ``n`` edges has 2 (even ``k``) or ``2(n − k)`` (odd ``k``) valid
   assignments (:func:`valid_assignments`). Each is scored by deforming the template into the
   target pose (``E_d + E_pose``, Eq. 1) and the cheapest kept, region by region. For odd
   ``k`` the paper searches the cusp with optuna's TPE; physlab scans every ``s``-th cusp
   position then refines around the best (a deterministic coarse-to-fine substitute, no extra
   dependency). Overlapping regions are scored the same way, one at a time with the others
   fixed (Algorithm 1): region ``r``'s ``b_i`` chooses between its base triangles and its own
   pocket at each of its outline edges, whatever other layers cover the place. **Non-manifold edges** (Sec. 4.3): near multi-valence joints (chest, pelvis)
   the outline edge closest to the joint that a bone crosses keeps both layers attached.
5. **Depth of layers** (Sec. 5.1): bounded biharmonic weights of the handles on the layered
   (non-manifold) mesh (libigl ``bbw``) times the handles' depths give every vertex a depth;
   the layer with the smaller mean depth in a region is its front layer. Where regions overlap,
   each connected piece of equal cover sorts its ``m + 1`` layers by mean depth
   (:attr:`LayeredTemplate.layer_rank`: 0 the visible layer, ``k`` the ``k``-th hidden one).
   Triangles are drawn back to front by this depth in every frame (painter's algorithm), so a
   limb that moves over the body is drawn over it.
6. **Texturing** (Sec. 5.1): the base mesh and each front layer take the keyframe; a back
   layer takes the *other* keyframe where, deformed into that pose, its triangle lands fully on
   the other key's foreground and outside its occlusion regions, and is inpainted elsewhere
   (OpenCV Telea as the stand-in for LaMa; ``inpainter=`` is the seam). The ``k``-th hidden
   layer has its own band of the texture atlas (where three parts overlap, the middle and the
   back layer carry different textures). The inpainted
   texels are kept as a mask of the texture atlas (:attr:`LayeredTemplate.inpainted`, a texture
   channel): :meth:`LayeredTemplate.render_inpainted` draws it like the texture, so every
   deformed frame knows which of its visible pixels were inpainted — the area whose IoU is the
   texture quality q(I) of the blending costs (Sec. 5.2; :func:`~physlab.inbetween.blend.
   texture_quality`). :attr:`LayeredTemplate.inpainted_fraction` is its share of the back
   layers' area.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import sparse

from .template import Template, as_rgba_float, classical_foreground_mask

__all__ = ["Occlusion", "OcclusionRegion", "LayeredTemplate", "valid_assignments",
           "count_valid_assignments", "refine_through_t_junctions", "switch_points", "incise",
           "sew_pockets",
           "build_layered_template", "suggest_occlusions", "suggest_t_junctions", "bone_widths",
           "save_occlusions", "load_occlusions", "limb_overlaps", "limb_chain", "limb_contact",
           "REGION_EXTENTS"]

#: A T-junction may lie at most this far (px) from its region's outline.
T_JUNCTION_TOLERANCE = 6.0
#: Outline vertices farther than this (px) from every T-junction stay fixed while the outline
#: is pulled through the T-junctions (Sec. 4.1).
REFINE_RADIUS = 24.0
#: Candidate cusp positions scanned before refinement (odd ``k``).
CUSP_SCAN = 8
#: Iterations per solve when an assignment is scored (see build_layered_template).
SCORE_MAX_ITER = 200
#: Gaps enclosed by the foreground at least this big (px²) are holes of the mesh.
MIN_HOLE_AREA = 16
#: About how many triangles each occlusion region is meshed with.
REGION_TRIANGLES = 60


# ------------------------------------------------------------------------------- Occlusion
@dataclass(frozen=True, eq=False)
class Occlusion:
    """One occlusion region of a keyframe (Brodt & Bessmeltsev Sec. 4).

    Parameters
    ----------
    mask : (H, W) bool array, or a polygon (k, 2) of pixel points ``(x, y)``.
    t_junctions : (m, 2) pixel points on the region's outline where one outline ends against
        another (Fig. 7); may be empty.
    label : str, free text (e.g. which parts overlap).
    limb : tuple of joint names, each naming the bone it ends (e.g. ``("left_elbow",
        "left_hand")``: upper arm + forearm), the limb whose region it is; empty (default):
        none. With a limb, :func:`build_layered_template` puts the handles of those bones
        (both joints and the midpoint of each) on one layer and the region's other handles on
        the other, the farther group in the pocket (by bone), instead of splitting the handles
        at their largest depth gap (Secs. 4.2, 5.1), which may cut a limb in two.

    Raises
    ------
    ValueError for an empty mask, a polygon with fewer than 3 points, NaN points, a ``limb``
    that is not a sequence of joint names.
    """

    mask: np.ndarray
    t_junctions: np.ndarray = ()
    label: str = ""
    limb: tuple = ()

    def __post_init__(self):
        m = np.asarray(self.mask)
        if m.ndim == 2 and m.shape[1] == 2 and m.dtype.kind == "f":
            if len(m) < 3 or not np.all(np.isfinite(m)):
                raise ValueError(f"Occlusion polygon needs >= 3 finite points, got {m.shape}")
            m = m.astype(np.float64)
        elif m.ndim == 2:
            if m.dtype != bool:
                if not np.isin(np.unique(m), (0, 1)).all():
                    raise ValueError("Occlusion mask must be boolean (or 0/1), or a (k, 2) "
                                     "float polygon")
                m = m.astype(bool)
            if not m.any():
                raise ValueError("Occlusion mask is empty")
        else:
            raise ValueError(f"Occlusion mask must be (H, W) bool or a (k, 2) float polygon, "
                             f"got shape {m.shape}")
        tj = np.asarray(self.t_junctions, dtype=np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(tj)):
            raise ValueError("t_junctions contain NaN or inf")
        limb = self.limb
        if isinstance(limb, str) or not isinstance(limb, (tuple, list)) \
                or not all(isinstance(j, str) for j in limb):
            raise ValueError(f"Occlusion limb must be a tuple of joint names (bones named by "
                             f"their end joint), e.g. ('left_elbow', 'left_hand'), got {limb!r}")
        object.__setattr__(self, "mask", m)
        object.__setattr__(self, "t_junctions", tj)
        object.__setattr__(self, "limb", tuple(limb))

    def __repr__(self):
        kind = "polygon" if self.is_polygon else f"mask {self.mask.shape[1]}x{self.mask.shape[0]}"
        limb = f", limb={self.limb!r}" if self.limb else ""
        return (f"Occlusion({kind}, {len(self.t_junctions)} T-junctions, "
                f"label={self.label!r}{limb})")

    @property
    def is_polygon(self):
        return self.mask.dtype != bool

    def mask_array(self, shape):
        """(H, W) bool mask of the region (polygons rasterised at pixel centres)."""
        H, W = shape
        if not self.is_polygon:
            if self.mask.shape != (H, W):
                raise ValueError(f"occlusion mask shape {self.mask.shape} differs from the "
                                 f"image's {(H, W)}")
            return self.mask
        from matplotlib.path import Path as MplPath

        yy, xx = np.mgrid[0:H, 0:W]
        return MplPath(self.mask).contains_points(
            np.c_[xx.ravel(), yy.ravel()]).reshape(H, W)

    def to_dict(self):
        """JSON-friendly dict: the outline polygon(s) of a mask are stored as points."""
        if self.is_polygon:
            poly = self.mask.tolist()
        else:
            from ..mesh import boundary_polygon

            poly = boundary_polygon(self.mask, epsilon=0.5).tolist()
        d = {"polygon": poly, "t_junctions": self.t_junctions.tolist(), "label": self.label}
        if self.limb:
            d["limb"] = list(self.limb)
        return d

    @classmethod
    def from_dict(cls, d, where="occlusion"):
        if not isinstance(d, dict) or "polygon" not in d:
            raise ValueError(f"{where}: expected an object with 'polygon' (list of [x, y]) and "
                             f"optional 't_junctions', 'label', 'limb'")
        try:
            return cls(np.asarray(d["polygon"], dtype=np.float64),
                       np.asarray(d.get("t_junctions", []), dtype=np.float64),
                       str(d.get("label", "")), d.get("limb", ()))
        except (TypeError, ValueError) as err:
            raise ValueError(f"{where}: {err}") from None


def save_occlusions(path, occlusions):
    """Write a list of :class:`Occlusion` as JSON (atomic: a failed write keeps the old file)."""
    from .._io import atomic_write_text

    data = {"occlusions": [o.to_dict() for o in occlusions]}
    atomic_write_text(Path(path), json.dumps(data, indent=1))


def load_occlusions(path):
    """Read :func:`save_occlusions`' JSON; errors name the file and the entry."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not valid JSON ({err})") from None
    items = data.get("occlusions") if isinstance(data, dict) else data
    if not isinstance(items, list):
        raise ValueError(f"{path}: expected {{'occlusions': [...]}} or a list of occlusions")
    return [Occlusion.from_dict(d, f"{path}: occlusions[{i}]") for i, d in enumerate(items)]


# ---------------------------------------------------------------------- switching rule
def valid_assignments(n, t_junctions):
    """All assignments ``b`` of one closed outline allowed by the switching rule (Eq. 2).

    The outline has vertices ``0..n−1`` and edges ``i = (i, i+1 mod n)``. ``b`` must switch
    (``b_{i−1} ≠ b_i``) at every T-junction vertex and may switch at most at one other vertex
    (a cusp); the number of switches around a loop is even, so a cusp appears exactly when the
    number ``k`` of T-junctions is odd.

    Parameters
    ----------
    n : int ≥ 3, edges (= vertices) of the loop.
    t_junctions : sequence of distinct vertex indices in ``0..n−1``.

    Returns
    -------
    list of ``(b, cusp)`` with ``b`` (n,) int8 in {0, 1} and ``cusp`` the cusp vertex or
    None: 2 entries for even ``k``, ``2 (n − k)`` for odd ``k``.
    """
    n = int(n)
    tj = sorted({int(v) for v in t_junctions})
    if n < 3:
        raise ValueError(f"an outline needs n >= 3 edges, got {n}")
    if len(tj) != len(list(t_junctions)):
        raise ValueError("t_junctions repeat a vertex; give each T-junction once")
    if tj and (tj[0] < 0 or tj[-1] >= n):
        raise ValueError(f"t_junctions must be vertex indices in 0..{n - 1}, got {tj}")
    if len(tj) >= n:
        raise ValueError(f"{len(tj)} T-junctions on an outline of {n} edges leave no edge "
                         "between them")

    def build(switches, first):
        b = np.empty(n, np.int8)   # b_i of edge i = (i, i+1); a switch at v: b_{v-1} != b_v
        b[0] = first
        for i in range(1, n):
            b[i] = 1 - b[i - 1] if i in switches else b[i - 1]
        return b

    out = []
    if len(tj) % 2 == 0:
        for first in (0, 1):
            out.append((build(set(tj), first), None))
    else:
        for c in range(n):
            if c in tj:
                continue
            for first in (0, 1):
                out.append((build(set(tj) | {c}, first), c))
    return out


def switch_points(points, labels, min_run=3):
    """Points of a closed outline where a boolean label along it switches (T-junctions).

    ``points`` (m, 2) in order around the loop, ``labels`` (m,) bool (e.g. "this outline point
    follows the occluder's silhouette"). Runs shorter than ``min_run`` points are absorbed by
    their neighbours first (pixel noise at the crossings). Returns (s, 2): the midpoint of each
    switching pair.
    """
    P = np.asarray(points, dtype=float)
    lab = np.asarray(labels, bool).copy()
    m = len(lab)
    for _ in range(m):
        sw = np.flatnonzero(lab != np.roll(lab, -1))
        if len(sw) < 2:
            break
        runs = np.diff(np.r_[sw, sw[0] + m])             # run after each switch
        short = np.argmin(runs)
        if runs[short] >= min_run:
            break
        idx = (sw[short] + 1 + np.arange(runs[short])) % m
        lab[idx] = ~lab[idx]
    sw = np.flatnonzero(lab != np.roll(lab, -1))
    return 0.5 * (P[sw] + P[(sw + 1) % m]) if len(sw) >= 2 else np.zeros((0, 2))


def count_valid_assignments(n, k):
    """Number of valid assignments of an outline of ``n`` edges with ``k`` T-junctions:
    2 for even ``k``, ``2 (n − k)`` for odd ``k`` (Sec. 4.4)."""
    return 2 if k % 2 == 0 else 2 * (n - k)


# ---------------------------------------------------------------------- regions, meshing
def _project_on_segments(Q, A, B):
    """Nearest points of segments ``A[j] → B[j]`` (k, 2) to points ``Q`` (m, 2): returns
    ``(proj (m, k, 2), dist (m, k))``."""
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    AB = B - A
    t = np.clip(np.einsum("mkd,kd->mk", Q[:, None] - A[None], AB)
                / np.maximum(np.einsum("kd,kd->k", AB, AB), 1e-12), 0.0, 1.0)
    proj = A[None] + t[..., None] * AB[None]
    return proj, np.linalg.norm(proj - Q[:, None], axis=2)


def _insert_on_outline(P, q):
    """Insert the projection of ``q`` onto polygon ``P``'s nearest edge as a vertex (unless a
    vertex is within 1 px); returns (P', index of that vertex, distance from q)."""
    proj, d = _project_on_segments(q, P, np.roll(P, -1, axis=0))
    proj, d = proj[0], d[0]
    e = int(np.argmin(d))
    dv = np.linalg.norm(P - proj[e], axis=1)  # an existing vertex at the projection: reuse it
    if dv.min() <= 1.0:
        v = int(np.argmin(dv))
        return P, v, float(np.linalg.norm(P[v] - q))
    return np.insert(P, e + 1, proj[e], axis=0), e + 1, float(d[e])


def refine_through_t_junctions(polygon, t_junctions, radius=REFINE_RADIUS,
                               tolerance=T_JUNCTION_TOLERANCE, where="occlusion"):
    """Deform an occlusion outline so it passes through its T-junctions (Sec. 4.1).

    The outline point nearest each T-junction becomes a vertex; the polygon is triangulated
    and deformed by minimising the symmetric Dirichlet energy plus the pose term (Eq. 1's
    energies) with that vertex pulled onto the T-junction and every outline vertex farther
    than ``radius`` px from all T-junctions held in place.

    Returns
    -------
    (P, tj_index): the refined polygon (k', 2) (T-junctions exactly on it) and the vertex index
    of each T-junction.

    Raises
    ------
    ValueError naming the T-junction that lies more than ``tolerance`` px from the outline.
    """
    from ..mesh import triangulate_polygon
    from .deform import SymmetricDirichletDeformer

    P = np.asarray(polygon, dtype=float)
    tjs = np.asarray(t_junctions, dtype=float).reshape(-1, 2)
    if not len(tjs):
        return P, np.zeros(0, np.int64)
    idx = []
    for i, q in enumerate(tjs):
        P2, v, d = _insert_on_outline(P, q)
        if d > tolerance:
            raise ValueError(f"{where}: t_junctions[{i}] at ({q[0]:.1f}, {q[1]:.1f}) lies "
                             f"{d:.1f} px from the occlusion mask's outline (at most "
                             f"{tolerance:g} px): move it onto the outline, where one drawn line "
                             "ends against another")
        if P2 is not P:
            idx = [j + 1 if j >= v else j for j in idx]
        P = P2
        idx.append(v)
    idx = np.asarray(idx, np.int64)
    if len(set(idx.tolist())) != len(idx):
        raise ValueError(f"{where}: two T-junctions snap to the same outline point; keep "
                         "T-junctions at least 2 px apart")
    moved = tjs - P[idx]
    if np.abs(moved).max() < 1e-9:
        return P, idx
    from scipy.spatial import cKDTree

    mesh = triangulate_polygon(P, min_angle=20.0)
    vid = cKDTree(mesh.X).query(P)[1]  # the outline's vertices in the mesh
    far = np.linalg.norm(P[:, None] - tjs[None], axis=2).min(axis=1) > radius
    fixed = np.flatnonzero(far)
    rows = vid[np.concatenate([idx, fixed])]
    B = sparse.csr_matrix((np.ones(len(rows)), (np.arange(len(rows)), rows)),
                          shape=(len(rows), mesh.n))
    targets = np.concatenate([tjs, P[fixed]])
    D = SymmetricDirichletDeformer(mesh.X, mesh.tris, B, mu=200.0)
    x = D.solve(targets, x0=mesh.X.copy()).x
    P = x[vid].copy()
    P[idx] = tjs  # exactly on them (the pose term leaves sub-pixel residuals)
    return P, idx


@dataclass
class OcclusionRegion:
    """One region of a :class:`LayeredTemplate`.

    Attributes
    ----------
    loop : (n,) int, the outline's vertices in order (ids of the base mesh, layer A).
    t_junctions : (k,) int positions in ``loop`` of the T-junctions.
    non_manifold : (n,) bool per outline edge ``(loop[i], loop[i+1])``: both layers stay
        attached (Sec. 4.3).
    tris_a, tris_b : int indices into the template's triangles: the base mesh's triangles in
        the region (layer A) and the pocket's (layer B).
    b : (n,) int8, the chosen assignment (0: layer A attached to the outside at that edge,
        1: layer B), ``cusp`` its cusp vertex or None.
    energies : list of (b, cusp, energy) of every assignment tried.
    front : "A" or "B", the layer in front (Sec. 5.1), ``depth`` (2,) mean layer depths, over
        the whole region (where it overlaps other regions the triangles' order is
        :attr:`LayeredTemplate.layer_rank`).
    label : the :class:`Occlusion`'s label.
    overlaps : indices of the other regions it overlaps (a third layer or more there).
    """

    loop: np.ndarray
    t_junctions: np.ndarray
    non_manifold: np.ndarray
    tris_a: np.ndarray
    tris_b: np.ndarray
    pocket_of: dict
    b: np.ndarray = None
    cusp: int = None
    energies: list = field(default_factory=list)
    front: str = "A"
    depth: np.ndarray = None
    label: str = ""
    overlaps: tuple = ()

    @property
    def n_edges(self):
        return len(self.loop)

    def visible_edges(self):
        """(n,) bool: outline edges that are *visible* occlusion contours — the front layer is
        cut there (Fig. 6: blue); the others are hidden contours (red)."""
        front_attached = 0 if self.front == "A" else 1
        return (self.b != front_attached) & ~self.non_manifold


def _loop_of(tris_in):
    """Ordered outline (longest boundary loop) of a set of triangles."""
    E = np.concatenate([tris_in[:, [0, 1]], tris_in[:, [1, 2]], tris_in[:, [2, 0]]])
    key = np.sort(E, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    bnd = E[counts[inv.ravel()] == 1]  # oriented boundary edges (triangles are CCW)
    nxt = {}
    for a, c in bnd:
        nxt.setdefault(int(a), []).append(int(c))
    loops, seen = [], set()
    for start in list(nxt):
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen:
            seen.add(v)
            loop.append(v)
            cand = [w for w in nxt.get(v, []) if w not in seen]
            if not cand:
                break
            v = cand[0]
        loops.append(loop)
    return np.asarray(max(loops, key=len), np.int64)


def _segments_cross(p0, p1, q0, q1):
    def orient(a, b, c):
        return np.sign((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
                       - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))
    return (orient(p0, p1, q0) * orient(p0, p1, q1) < 0) & \
        (orient(q0, q1, p0) * orient(q0, q1, p1) < 0)


def _non_manifold_edges(X, loop, skeleton):
    """Sec. 4.3's heuristic: for each multi-valence joint (≥ 3 bones) lying inside the region
    (where the two layers' body parts meet, e.g. a hip inside a thigh-over-belly overlap), the
    outline edge closest to it that a bone crosses in 2D keeps both layers attached.

    The paper picks the closest crossed edge to such joints without asking for the joint to be
    inside; on a forearm lying across the belly near the chest that glues the forearm to the
    torso, so physlab asks for it (a documented difference)."""
    from matplotlib.path import Path as MplPath

    n = len(loop)
    nm = np.zeros(n, bool)
    A, B = X[loop], X[np.roll(loop, -1)]
    bones = skeleton.bones
    valence = np.bincount(bones.ravel(), minlength=len(skeleton))
    crossed = np.zeros(n, bool)
    for p, c in bones:
        crossed |= _segments_cross(A, B, skeleton.xy[p][None], skeleton.xy[c][None])
    if not crossed.any():
        return nm
    inside = MplPath(A).contains_points(skeleton.xy)
    mid = 0.5 * (A + B)
    for j in np.flatnonzero((valence >= 3) & inside):
        d = np.linalg.norm(mid - skeleton.xy[j], axis=1)
        cand = np.flatnonzero(crossed)
        nm[cand[np.argmin(d[cand])]] = True
    return nm


@dataclass(frozen=True, eq=False)
class LayeredTemplate(Template):
    """A :class:`~physlab.inbetween.template.Template` with occlusion layers.

    Extra attributes
    ----------------
    regions : list of :class:`OcclusionRegion`.
    vertex_layer : (n,) int8, 0 for the base mesh, 1 for pocket vertices.
    layer_rank : (T,) int8, depth rank of every triangle among the layers stacked where it lies
        (Sec. 5.1): 0 visible in the keyframe, 1 the first hidden layer, 2 the one behind it
        (where two occlusion regions overlap), …; :attr:`n_layers` is ``1 + max``.
    handle_weights : (n, K) float, bounded biharmonic weights of the handles (Sec. 5.1).
    handle_depth : (K,) float, depth of each handle (joints, then bone midpoints) at rest.
    texture : ((1 + K) H, W, 4) float32 atlas, ``K = max(1, n_layers − 1)``: the keyframe on
        top, below it one band per hidden rank (``(2H, W, 4)`` with two layers).
    tex_coords : (T, 3, 2) texture position of every triangle corner in the atlas.
    inpainted_fraction : float in [0, 1], share of back-layer area that had to be inpainted
        (0 without occlusions).
    inpainted : ((1 + K) H, W) bool mask of the atlas: the texels of ``texture`` that came from
        inpainting (Sec. 5.1); the top half (the keyframe) is all False, and so is everything
        without back layers. :meth:`render_inpainted` draws it into a pose.
    occlusions : list of the :class:`Occlusion` it was built from.
    """

    regions: list = field(default_factory=list)
    vertex_layer: np.ndarray = None
    handle_weights: np.ndarray = None
    handle_depth: np.ndarray = None
    texture: np.ndarray = None
    tex_coords: np.ndarray = None
    inpainted_fraction: float = 0.0
    occlusions: list = field(default_factory=list)
    inpainted: np.ndarray = None
    layer_rank: np.ndarray = None

    def __repr__(self):
        h, w = self.image.shape[:2]
        return (f"LayeredTemplate({self.mesh.n} vertices, {self.mesh.n_tris} triangles, "
                f"{len(self.regions)} occlusion region(s), image {h}x{w})")

    def triangle_depth(self, skeleton=None):
        """(T,) depth of every triangle (mean of its vertices' skinned depths) at the pose of
        ``skeleton`` (default: the template's own); smaller = nearer."""
        d = self.handle_depth if skeleton is None or skeleton.depth is None \
            else _handle_depth(skeleton)
        if d is None:
            return np.zeros(self.mesh.n_tris)
        v = self.handle_weights @ d
        return v[self.mesh.tris].mean(axis=1)

    @property
    def back_triangles(self):
        """(T,) bool: the triangles of the back layers (Sec. 5.1), textured from the atlas'
        lower half."""
        if self.layer_rank is not None:
            return self.layer_rank > 0
        back = np.zeros(self.mesh.n_tris, bool)
        for reg in self.regions:
            back[reg.tris_b if reg.front == "A" else reg.tris_a] = True
        return back

    @property
    def n_layers(self):
        """Most layers stacked anywhere: 1 (a single sheet), 2 (pockets), 3+ where occlusion
        regions overlap."""
        return 1 + (int(self.layer_rank.max()) if self.layer_rank is not None
                    and len(self.layer_rank) else 0)

    def _draw(self, texture, x, out_shape, supersample, skeleton, triangles=None):
        """Warp an atlas-shaped ``texture`` by the triangles (all, or the index array
        ``triangles``) in back-to-front order at ``skeleton``'s pose."""
        from ..render import warp_texture

        x = np.asarray(x, dtype=float)
        order = np.argsort(-self.triangle_depth(skeleton), kind="stable")
        if triangles is not None:
            order = order[np.isin(order, triangles)]
        tris = self.mesh.tris[order]
        corners = x[tris].reshape(-1, 2)
        uv = self.tex_coords[order].reshape(-1, 2)
        T = len(tris)
        return warp_texture(texture, uv, corners, np.arange(3 * T).reshape(T, 3),
                            self.shape if out_shape is None else out_shape,
                            supersample=supersample)

    def render(self, x, out_shape=None, supersample=2, skeleton=None):
        """The textured layered template at deformed vertices ``x`` (n, 2), triangles drawn back
        to front by their skinned depth at ``skeleton``'s pose (painter's algorithm).

        Returns (H, W, 4) float32 straight RGBA.
        """
        return self._draw(self.texture, x, out_shape, supersample, skeleton)

    def render_inpainted(self, x, out_shape=None, supersample=2, skeleton=None,
                         triangles=None):
        """The visible pixels whose texture came from inpainting, at deformed vertices ``x``.

        The atlas mask :attr:`inpainted` is a texture channel: it is drawn exactly as
        :meth:`render` draws the texture (same triangles, same back-to-front order, same
        antialiasing, the texture's alpha as coverage), so a pixel is marked when more than
        half of what is *visible* there — the front-most triangles — was sampled from inpainted
        texels. These are the pixels ``A`` of the texture quality
        ``q(I) = 1 − |A ∩ F| / |F|`` (Brodt & Bessmeltsev 2024, Sec. 5.2;
        :func:`~physlab.inbetween.blend.texture_quality`). At the rest pose the back layers
        lie under their front layers, so nothing is visible: ``q = 1`` at the own keyframe,
        as the paper notes.

        Parameters
        ----------
        x : (n, 2) float deformed vertex positions (pixels).
        out_shape : (H, W), default the keyframe's size.
        supersample : int ≥ 1, as :meth:`render`.
        skeleton : Skeleton of the pose (joint depths order the triangles), default the
            template's own.
        triangles : None (all), or an int array / (T,) bool mask of the triangles to draw,
            e.g. :attr:`back_triangles` alone (then the hidden back layers show).

        Returns
        -------
        (H, W) bool.
        """
        x = np.asarray(x, dtype=float)
        if x.shape != self.X.shape:
            raise ValueError(f"x must have shape {self.X.shape} (one position per template "
                             f"vertex), got {x.shape}")
        if triangles is not None:
            tr = np.asarray(triangles)
            if tr.dtype == bool:
                if tr.shape != (self.mesh.n_tris,):
                    raise ValueError(f"triangles as a bool mask must have shape "
                                     f"({self.mesh.n_tris},), got {tr.shape}")
                tr = np.flatnonzero(tr)
            elif tr.ndim != 1 or not np.issubdtype(tr.dtype, np.integer) or (
                    tr.size and (tr.min() < 0 or tr.max() >= self.mesh.n_tris)):
                raise ValueError(f"triangles must be indices in 0..{self.mesh.n_tris - 1} or a "
                                 f"({self.mesh.n_tris},) bool mask")
            triangles = tr
        H, W = self.shape if out_shape is None else (int(out_shape[0]), int(out_shape[1]))
        if self.inpainted is None or not self.inpainted.any():
            return np.zeros((H, W), bool)
        chan = np.empty(self.texture.shape, np.float32)              # (2H, W, 4)
        chan[..., :3] = self.inpainted[..., None]
        chan[..., 3] = self.texture[..., 3]                          # coverage as the texture's
        out = self._draw(chan, x, (H, W), supersample, skeleton, triangles)
        return (out[..., 0] > 0.5) & (out[..., 3] > 0.0)


def _triangle_cells(tris, regions):
    """Which regions cover each base triangle, and the connected pieces of equal cover.

    Returns ``(cover (T, R) bool, cell (T,) int)``: triangles sharing an edge and covered by
    the same regions are in one cell (a cell covered by ``m`` regions has ``m + 1`` layers)."""
    from scipy.sparse.csgraph import connected_components

    T = len(tris)
    cover = np.zeros((T, len(regions)), bool)
    for r, reg in enumerate(regions):
        cover[reg.tris_a, r] = True
    _, sig = np.unique(cover, axis=0, return_inverse=True)
    sig = sig.ravel()
    E = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    tid = np.tile(np.arange(T), 3)
    order = np.lexsort((E[:, 1], E[:, 0]))
    E, tid = E[order], tid[order]
    shared = np.all(E[1:] == E[:-1], axis=1)
    a, b = tid[:-1][shared], tid[1:][shared]
    keep = sig[a] == sig[b]
    graph = sparse.coo_matrix((np.ones(keep.sum()), (a[keep], b[keep])), shape=(T, T))
    return cover, connected_components(graph, directed=False)[1]


def _depth_clusters(levels, k):
    """Cluster the sorted distinct depths ``levels`` into ``k`` groups at the ``k − 1`` largest
    gaps; returns (len(levels),) int group of each level, 0 = nearest."""
    if k <= 1 or len(levels) <= 1:
        return np.zeros(len(levels), np.int64)
    gaps = np.argsort(-np.diff(levels), kind="stable")[:k - 1]
    group = np.zeros(len(levels), np.int64)
    for g in gaps:
        group[g + 1:] += 1
    return group


def _hidden_depths(mesh, skeleton, cover, samples=32):
    """(R,) depth of the part each region hides, read off the skeleton where the region does
    not overlap another: the deepest point of the bones (``samples`` points each, depth linear
    between the joints) inside the region's own triangles; NaN where no bone passes there (a
    region nested inside another)."""
    from ..mesh import locate_points

    b = skeleton.bones
    s = np.linspace(0.0, 1.0, samples)[:, None, None]
    P = (skeleton.xy[b[:, 0]][None] + s * (skeleton.xy[b[:, 1]] - skeleton.xy[b[:, 0]])[None])
    D = (skeleton.depth[b[:, 0]][None] + s[..., 0] * (skeleton.depth[b[:, 1]]
                                                      - skeleton.depth[b[:, 0]])[None])
    t = np.atleast_1d(locate_points(mesh, P.reshape(-1, 2))[0]).astype(np.int64)
    D = D.ravel()
    inside = t >= 0
    own = cover.sum(axis=1) == 1                           # triangles of one region only
    out = np.full(cover.shape[1], np.nan)
    for r in range(cover.shape[1]):
        hit = inside.copy()
        hit[inside] = own[t[inside]] & cover[t[inside], r]
        if hit.any():
            out[r] = D[hit].max()
    return out


def _limb_handles(skeleton, limb, where="limb"):
    """(J + B,) bool over :meth:`Skeleton.handles` (joints, then bone midpoints): the handles
    of the bones ``limb`` (joint names, each naming the bone it ends) — both joints of each
    bone (the limb's root joint, where it is attached, included) and its midpoint.

    Raises ValueError naming ``where`` for an unknown joint or the root.
    """
    J = len(skeleton.names)
    child = np.flatnonzero(np.asarray(skeleton.parents) >= 0)      # bone k ends at child[k]
    out = np.zeros(J + len(child), bool)
    for joint in limb:
        _bone_of(skeleton, joint, where)
        j = skeleton.index(joint)
        out[[skeleton.parents[j], j, J + int(np.searchsorted(child, j))]] = True
    return out


def _limb_split(hs, hdepth, in_limb):
    """Which of a region's handles go into its pocket when the region is a limb's (by bone):
    ``(len(hs),) bool``, the limb's handles (``in_limb`` (K,) bool) all on one layer and the
    region's other handles on the other, the group of larger mean depth (``hdepth`` (K,),
    smaller = nearer) in the pocket. All on the base layer when one group is empty or the
    means tie (as the depth split does for equal depths)."""
    a = in_limb[hs]
    if a.all() or not a.any():
        return np.zeros(len(hs), bool)
    da, do = hdepth[hs][a].mean(), hdepth[hs][~a].mean()
    if abs(da - do) <= 1e-9:
        return np.zeros(len(hs), bool)
    return a if da > do else ~a


def _layered_handle_pockets(tri0, hdepth, cover, cell, hidden, name, limbs=None):
    """Layer of each handle when regions overlap (Sec. 4.2 with masks "one per layer, sorted by
    depth", Sec. 4): ``(K,) int``, the region whose pocket holds the handle, −1 for the base.

    A cell covered by one region splits its handles at the largest depth gap, nearer ones on
    the base layer, farther ones in the pocket (as without overlaps, but per connected cell).
    A cell covered by regions ``r_1 < … < r_m`` has ``m + 1`` layers stacked in the order the
    occlusions are listed — base, pocket of ``r_1``, …, pocket of ``r_m`` (front to back) —
    and the distinct joint depths of the handles in those regions, clustered into ``m + 1``
    groups at the largest gaps, put each handle on its layer.

    ``hidden`` (R,) is the depth of the part each region hides (:func:`_hidden_depths`, NaN
    when unknown). ``limbs`` (R,) list of (K,) bool or None (:func:`_limb_handles` of each
    region's :attr:`Occlusion.limb`): a cell covered by one region that has a limb splits its
    handles by bone instead (:func:`_limb_split`); cells of overlapping regions keep the depth
    clusters.

    Raises ValueError when the joints' depths have fewer distinct values than a cell has layers
    (they cannot order them), and when the order of the occlusions contradicts ``hidden`` (of
    two overlapping regions, the one listed first must hide the nearer part).
    """
    K = len(tri0)
    out = np.full(K, -1, np.int64)
    hcell = cell[tri0]
    hcover = cover[tri0]                                   # (K, R)
    for c in np.unique(cell[cover.sum(axis=1) == 1]):
        rs = np.flatnonzero(cover[np.flatnonzero(cell == c)[0]])
        hs = np.flatnonzero(hcell == c)
        if len(hs) and limbs is not None and limbs[rs[0]] is not None:
            out[hs[_limb_split(hs, hdepth, limbs[rs[0]])]] = rs[0]
        elif len(hs) and np.ptp(hdepth[hs]) > 1e-9:
            d = np.sort(hdepth[hs])
            gap = np.argmax(np.diff(d))
            out[hs[hdepth[hs] > 0.5 * (d[gap] + d[gap + 1])]] = rs[0]
    for c in np.unique(cell[cover.sum(axis=1) > 1]):
        rs = np.flatnonzero(cover[np.flatnonzero(cell == c)[0]])
        L = len(rs) + 1
        near = np.flatnonzero(hcover[:, rs].any(axis=1))   # handles in any of these regions
        levels = np.unique(np.round(hdepth[near], 9))
        which = " and ".join(f"occlusions[{r}]" for r in rs)
        if len(levels) < L:
            raise ValueError(
                f"{name}: {which} overlap, so {L} layers lie there, but the joints in those "
                f"regions have only {len(levels)} distinct depth(s) {levels.tolist()} in "
                f"skeleton.depth: give the {L} overlapping parts {L} different depths "
                "(smaller = nearer), e.g. skeleton.with_depth({'left_hand': -1.0, "
                "'right_hand': 1.0})")
        group = _depth_clusters(levels, L)
        h = hidden[rs]                                     # the order must match the depths
        known = np.flatnonzero(np.isfinite(h))
        bad = np.flatnonzero(np.diff(h[known]) < -1e-9)
        if len(bad):
            a, b = rs[known[bad[0]]], rs[known[bad[0] + 1]]
            raise ValueError(
                f"{name}: occlusions are listed in an order the joint depths contradict: "
                f"occlusions[{a}] comes before occlusions[{b}], which overlaps it, but hides a "
                f"deeper part (depth {hidden[a]:g} > {hidden[b]:g} in skeleton.depth). List "
                "overlapping occlusions nearest hidden part first (one mask per layer, sorted "
                f"by depth, Sec. 4): put occlusions[{b}] before occlusions[{a}]")
        hs = np.flatnonzero(hcell == c)
        if len(hs):
            g = group[np.searchsorted(levels, np.round(hdepth[hs], 9))]
            out[hs] = np.where(g > 0, rs[np.maximum(g - 1, 0)], -1)
    return out


def _handle_depth(skeleton):
    if skeleton.depth is None:
        return None
    b = skeleton.bones
    return np.concatenate([skeleton.depth, 0.5 * (skeleton.depth[b[:, 0]] + skeleton.depth[b[:, 1]])])


def incise(tris, regions, assignments, n_vertices=None):
    """Cut every region's pocket loose along its outline by vertex re-indexing (Algorithm 1).

    For each outline vertex and each layer: the layer keeps the shared (base-mesh) vertex when
    at least one of the vertex's two outline edges attaches that layer to the outside
    (``b`` picks the layer; non-manifold edges attach both), else it gets its own copy — so a
    layer is cut exactly along the edges where it is not attached, and the cut ends at
    T-junctions and cusps.

    Parameters
    ----------
    tris : (T, 3) int triangles of the sewn template (base mesh + pockets).
    regions : list of :class:`OcclusionRegion`.
    assignments : list of (n_r,) int8 ``b`` per region.
    n_vertices : int, vertices of the sewn template (default ``tris.max() + 1``).

    Where regions overlap (:attr:`OcclusionRegion.overlaps`, nested pockets) an outline vertex
    may lie on several outlines, and the layers meeting there are more than two; then every
    outline vertex is split by what its edges attach (:func:`_incise_overlapping`): the
    triangles around it that stay connected — through edges inside a layer, and across each
    outline edge through the layer ``b`` attaches to the outside — keep one vertex, and every
    other connected group gets its own copy. With one region at a vertex this is the rule
    above.

    Returns
    -------
    (tris', n_new, copies): the re-indexed triangles, the number of vertices added, and the
    ``(original vertex, layer)`` of each added vertex (vertex ids ``n, n+1, …``; layer 0 for
    copies in the base mesh, 1 in a pocket).
    """
    tris = np.array(tris, copy=True)
    n0 = int(tris.max()) + 1 if n_vertices is None else int(n_vertices)
    if any(len(reg.overlaps) for reg in regions):
        return _incise_overlapping(tris, regions, assignments, n0)
    copies = []
    for reg, b in zip(regions, assignments):
        n = reg.n_edges
        b = np.asarray(b)
        prev = np.roll(np.arange(n), 1)
        for layer, sel, ids in ((0, reg.tris_a, None), (1, reg.tris_b, reg.pocket_of)):
            attached = (b == layer) | reg.non_manifold        # per edge i = (v_i, v_i+1)
            keep = attached | attached[prev]                  # per vertex: either edge
            for i in np.flatnonzero(~keep):
                v = int(reg.loop[i])
                new = n0 + len(copies)
                copies.append((v, layer))
                sub = tris[sel]
                sub[sub == v] = new
                tris[sel] = sub
    return tris, len(copies), copies


def sew_pockets(X, tris, region_tris):
    """The initial template (Sec. 4.2): every region's triangles duplicated as one more layer —
    a *pocket* — sewn to the mesh along the region's outline.

    The pocket copies the region's vertices except those on its outline (the longest boundary
    loop of its triangles), so it shares exactly the outline with the base mesh. Regions may
    overlap (masks "one per layer", Sec. 4): each pocket covers its whole region, so where
    ``m`` regions overlap there are ``m + 1`` layers — the base mesh and one pocket per region
    — and a region's outline running inside another region is sewn to the base layer there
    while the other region's pocket runs across it (nested pockets).

    Parameters
    ----------
    X : (n, 2) float base-mesh vertices.
    tris : (T, 3) int base-mesh triangles.
    region_tris : list of int index arrays into ``tris``, the triangles of each region.

    Returns
    -------
    (X_all (n + p, 2), tris_all (T + Σ|region|, 3), regions): the sewn template (pockets
    appended in region order) and one :class:`OcclusionRegion` per region with ``loop``,
    ``tris_a``, ``tris_b``, ``pocket_of``, ``overlaps`` set (no T-junctions, no non-manifold
    edges yet).
    """
    X = np.asarray(X, dtype=float)
    tris = np.asarray(tris)
    regions, pocket_tris, pocket_X = [], [], []
    n_base = len(X)
    for sel in region_tris:
        sel = np.asarray(sel)
        loop = _loop_of(tris[sel])
        # pocket: copies of the region's interior vertices, outline shared
        verts = np.unique(tris[sel])
        interior = np.setdiff1d(verts, loop)
        start = n_base + sum(len(p) for p in pocket_X)
        pocket_of = {int(v): start + i for i, v in enumerate(interior)}
        pocket_X.append(X[interior])
        pt = tris[sel].copy()
        for v, w in pocket_of.items():
            pt[tris[sel] == v] = w
        first_b = len(tris) + sum(len(p) for p in pocket_tris)
        pocket_tris.append(pt)
        regions.append(OcclusionRegion(
            loop=loop, t_junctions=np.zeros(0, np.int64), non_manifold=np.zeros(len(loop), bool),
            tris_a=sel, tris_b=np.arange(first_b, first_b + len(sel)), pocket_of=pocket_of))
    for r, reg in enumerate(regions):
        reg.overlaps = tuple(q for q, other in enumerate(regions)
                             if q != r and np.intersect1d(reg.tris_a, other.tris_a).size)
    X_all = np.concatenate([X] + pocket_X) if pocket_X else X
    tris_all = np.concatenate([tris] + pocket_tris) if pocket_tris else tris
    return X_all, tris_all, regions


def _incise_overlapping(tris, regions, assignments, n0):
    """:func:`incise` for overlapping regions: split every outline vertex into the connected
    groups of its triangles (union–find over the edges at the vertex; an outline edge of
    region ``r`` joins the triangles outside ``r`` with ``r``'s base triangles if ``b_i = 0``,
    with its pocket if ``b_i = 1``, with both on non-manifold edges; any other edge joins the
    triangles of one layer sharing it — a chord between two outline vertices is shared by the
    base and the pocket, which stay apart there). The group of the vertex's first triangle
    keeps the id."""
    orig = np.asarray(tris)
    tris = orig.copy()
    layer = np.full(len(orig), -1, np.int64)           # -1 base mesh, r the pocket of region r
    member = []                                        # per region: 0 outside, 1 base, 2 pocket
    for r, reg in enumerate(regions):
        m = np.zeros(len(orig), np.int8)
        m[reg.tris_a], m[reg.tris_b] = 1, 2
        layer[reg.tris_b] = r
        member.append(m)
    pocket = layer >= 0
    on_loop = {}
    for r, (reg, b) in enumerate(zip(regions, assignments)):
        n = reg.n_edges
        for i in range(n):
            u, v = int(reg.loop[i]), int(reg.loop[(i + 1) % n])
            on_loop.setdefault((min(u, v), max(u, v)), []).append(
                (r, int(np.asarray(b)[i]), bool(reg.non_manifold[i])))
    copies = []
    for v in sorted({int(w) for reg in regions for w in reg.loop}):
        ts = np.flatnonzero((orig == v).any(axis=1))
        parent = {int(t): int(t) for t in ts}

        def find(t):
            while parent[t] != t:
                parent[t] = parent[parent[t]]
                t = parent[t]
            return t

        def join(group):
            group = [int(t) for t in group]
            for t in group[1:]:
                parent[find(t)] = find(group[0])

        for u in np.unique(orig[ts]):
            if u == v:
                continue
            share = ts[(orig[ts] == u).any(axis=1)]
            rules = on_loop.get((min(v, int(u)), max(v, int(u))))
            if not rules:
                for lay in np.unique(layer[share]):
                    join(share[layer[share] == lay])
                continue
            for r, b, nm in rules:
                kind = member[r][share]
                out = share[(kind == 0) & ~pocket[share]]      # the base mesh outside r
                if b == 0 or nm:
                    join(np.r_[out, share[kind == 1]])
                if b == 1 or nm:
                    join(np.r_[out, share[kind == 2]])
                join(out)
        roots = np.array([find(int(t)) for t in ts])
        keep = roots[0]
        for root in dict.fromkeys(roots.tolist()):
            if root == keep:
                continue
            group = ts[roots == root]
            new = n0 + len(copies)
            copies.append((v, 1 if pocket[group].all() else 0))
            sub = tris[group]
            sub[orig[group] == v] = new
            tris[group] = sub
    return tris, len(copies), copies


def _expand(X, copies):
    return np.concatenate([X, X[[v for v, _ in copies]]]) if copies else X


def build_layered_template(image, skeleton, occlusions=(), mask=None, mask_predictor=None,
                           max_area=None, epsilon=2.0, min_angle=20.0, grow=3,
                           target_skeletons=None, other_image=None, other_occlusions=(),
                           other_mask=None, inpainter=None, mu=200.0, cusp_scan=CUSP_SCAN,
                           region_triangles=REGION_TRIANGLES, assignments=None,
                           score_max_iter=SCORE_MAX_ITER, name="keyframe"):
    """A keyframe's occlusion-aware template (Secs. 4.1–4.4, 5.1; module docstring).

    Parameters
    ----------
    image : (H, W, 3|4) keyframe.
    skeleton : Skeleton (pixels), with ``depth`` when regions hold limbs of different depth.
    occlusions : list of :class:`Occlusion` (empty: a single sheet, drawn in depth order).
        Regions may overlap: each adds a layer over its area (Sec. 4, "one mask per layer,
        sorted by depth"), and in an overlap the occlusion listed first hides the nearer part
        (e.g. ``[torso under the left forearm, right forearm under torso and left forearm]``).
        The handles inside a region go to its two layers by depth — split at their largest
        depth gap, the farther ones in the pocket (Secs. 4.2, 5.1) — or, for an occlusion with
        a :attr:`Occlusion.limb`, by bone: the limb's handles on one layer, the others on the
        other (where regions overlap, by the depth clusters either way).
    mask, mask_predictor, max_area, epsilon, min_angle, grow : as
        :func:`~physlab.inbetween.template.build_template`.
    target_skeletons : list of Skeletons the template is deformed through to score the
        topologies (e.g. the animation towards the other key); required with occlusions.
    other_image, other_occlusions, other_mask : the other keyframe (texture for back layers,
        Sec. 5.1); without it back layers are inpainted.
    inpainter : callable ``(rgba (H, W, 4) float, hole (H, W) bool) -> rgba`` (default OpenCV
        Telea on the colour, the seam for a learned inpainter).
    mu : pose weight μ of the scoring deformations.
    cusp_scan : int, cusp positions scanned before refinement (odd numbers of T-junctions).
    region_triangles : int, about how many triangles each occlusion region gets (its layers
        must bend with the limbs inside it; the rest of the mesh keeps ``max_area``).
    score_max_iter : int, iterations per solve when scoring an assignment (a wrong topology
        converges slowly: uncapped, scoring one took 20 s of the 21 s of a 512² template,
        capped at 200 the ranking is the same).
    assignments : None (choose by energy, Algorithm 1), or one index per region into
        :func:`valid_assignments` of that region's outline — a fixed topology, e.g. a hand
        annotation or the deliberately wrong one of the Fig. 8 experiment (the other indices'
        energies are not computed).
    name : str for messages.

    Returns
    -------
    LayeredTemplate.

    Raises
    ------
    ValueError for masks of another size, occlusions outside the foreground, T-junctions off
    their outline, a skeleton without depth when a region holds handles of both layers, a
    region repeating an earlier one (IoU > 0.8), overlapping regions whose joints have fewer
    distinct depths than the layers there, overlapping occlusions listed in an order the
    joint depths contradict, an occlusion's ``limb`` naming an unknown joint or the root…
    """
    from scipy import ndimage
    from scipy.spatial import cKDTree

    from ..mesh import TriMesh, boundary_polygon, locate_points
    from .template import keyframe_mask

    img, mask, grown = keyframe_mask(image, skeleton, mask, mask_predictor, grow, name)
    H, W = img.shape[:2]
    occlusions = list(occlusions or ())
    for i, o in enumerate(occlusions):
        if not isinstance(o, Occlusion):
            raise TypeError(f"{name}: occlusions[{i}] is a {type(o).__name__}, not an Occlusion")
    filled = ndimage.binary_fill_holes(grown)
    outer = boundary_polygon(filled, epsilon=epsilon, min_corner_angle=min_angle)
    # gaps enclosed by the figure (between crossed legs, an arm and the hip) stay holes
    gaps, n_gaps = ndimage.label(filled & ~grown)
    holes = [boundary_polygon(gaps == g, epsilon=epsilon)
             for g in range(1, n_gaps + 1) if (gaps == g).sum() >= MIN_HOLE_AREA]

    # ---- regions: masks inside the foreground, outlines through the T-junctions (Sec. 4.1)
    # by-bone handle layers of regions that are a limb's (Occlusion.limb)
    limbs = [_limb_handles(skeleton, o.limb, f"{name}: occlusions[{i}].limb") if o.limb
             else None for i, o in enumerate(occlusions)]
    if occlusions and skeleton.depth is None:
        raise ValueError(f"{name}: the skeleton has no joint depths, but occlusion layers need "
                         "the depth order of the joints near each region (Sec. 4): "
                         "skeleton.with_depth({'left_hand': -1.0, ...}) (smaller = nearer)")
    inner = ndimage.binary_erosion(mask, iterations=2)
    seen = np.zeros((H, W), bool)
    polys, tj_pos, labels, region_masks = [], [], [], []
    partners = []  # per region: the earlier regions it overlaps (a third layer there)
    for i, o in enumerate(occlusions):
        m = o.mask_array((H, W))
        outside = m & ~grown
        if outside.sum() > 0.05 * m.sum():
            raise ValueError(f"{name}: occlusions[{i}] ({o.label or 'unlabelled'}) lies "
                             f"{100 * outside.sum() / m.sum():.0f} % outside the foreground "
                             "mask; occlusion regions are parts of the drawing")
        m = m & inner
        partners.append([])
        if (m & seen).sum() > 0.05 * m.sum():   # more than two layers where they overlap
            for j, mj in enumerate(region_masks):
                both = (m & mj).sum()
                if not both:
                    continue
                iou = both / (m | mj).sum()
                if iou > 0.8:
                    raise ValueError(
                        f"{name}: occlusions[{i}] overlaps an earlier occlusion region, "
                        f"occlusions[{j}], almost entirely (IoU {iou:.2f}): each mask adds one "
                        "layer, so give one mask per layer (Sec. 4) — e.g. the second only "
                        "where three parts overlap — or merge the two")
                partners[i].append(j)
                partners[j].append(i)
        seen |= m
        region_masks.append(m)
        comps, k = ndimage.label(m)
        if k == 0:
            raise ValueError(f"{name}: occlusions[{i}] is empty inside the foreground")
        big = np.argmax(np.bincount(comps.ravel())[1:]) + 1
        P = boundary_polygon(comps == big, epsilon=epsilon)
        P, tj = refine_through_t_junctions(P, o.t_junctions, where=f"{name}: occlusions[{i}]")
        polys.append(P)
        tj_pos.append(P[tj])
        labels.append(o.label)

    # ---- base mesh with the outlines as constrained edges (Sec. 4.2)
    handles = skeleton.handles()
    dist_in = ndimage.distance_transform_edt(grown)
    ij = np.clip(np.round(handles[:, ::-1]).astype(int), 0, [H - 1, W - 1])
    ok = dist_in[ij[:, 0], ij[:, 1]] > epsilon + 1.5
    for P in polys:  # keep handles off the region outlines (no slivers)
        ok &= _project_on_segments(handles, P, np.roll(P, -1, axis=0))[1].min(axis=1) > 2.0
    cand = np.flatnonzero(ok)
    if len(cand):
        _, first = np.unique(np.round(handles[cand], 6), axis=0, return_index=True)
        cand = cand[np.sort(first)]
    if holes:  # handles inside a hole cannot be vertices
        from matplotlib.path import Path as _P

        for h in holes:
            cand = cand[~_P(h).contains_points(handles[cand])] if len(cand) else cand
    layered = any(partners)  # some regions overlap: cells of 3+ layers (nested pockets)
    cells = _cell_seeds(region_masks) if layered else None
    mesh = _triangulate_pslg(outer, polys, handles[cand], max_area, min_angle,
                             region_triangles, holes, cells)
    X, tris = mesh.X, mesh.tris
    cent = X[tris].mean(axis=1)
    from matplotlib.path import Path as MplPath

    in_any = np.zeros(len(tris), bool)
    claimed = []
    for r, P in enumerate(polys):
        # a triangle belongs to one region, except where regions overlap on purpose (then to
        # each: one more layer per region covering it)
        taken = np.zeros(len(tris), bool)
        for q, sel_q in enumerate(claimed):
            if q not in partners[r]:
                taken[sel_q] = True
        inside = MplPath(P).contains_points(cent) & (~taken if layered else ~in_any)
        if not inside.any():
            raise ValueError(f"{name}: occlusions[{r}] holds no triangle of the mesh (too small?)")
        in_any |= inside
        claimed.append(np.flatnonzero(inside))
    X_all, tris_all, regions = sew_pockets(X, tris, claimed)
    for r, reg in enumerate(regions):
        reg.t_junctions = np.asarray(cKDTree(X[reg.loop]).query(tj_pos[r])[1]
                                     if len(tj_pos[r]) else np.zeros(0, int), np.int64)
        reg.non_manifold = _non_manifold_edges(X, reg.loop, skeleton)
        reg.label = labels[r]
    n_base = len(X)
    vertex_layer = np.zeros(len(X_all), np.int8)
    vertex_layer[n_base:] = 1

    # ---- handles: vertices (layer by depth inside regions) or barycentric in a triangle
    hdepth = _handle_depth(skeleton)
    handle_tris = np.full(len(handles), -1, np.int64)
    handle_bary = np.zeros((len(handles), 3))
    handle_vertices = np.full(len(handles), -1, np.int64)
    base_mesh = TriMesh(X, tris)
    tri0, bary0 = locate_points(base_mesh, handles)
    tri0, bary0 = np.atleast_1d(tri0).astype(np.int64), np.atleast_2d(bary0)
    missing = np.flatnonzero(tri0 < 0)
    if missing.size:
        from ..mesh import _barycentric

        near_t = cKDTree(cent).query(handles[missing])[1]
        tri0[missing] = near_t
        bary0[missing] = _barycentric(X, tris, handles[missing], near_t)
    # pocket_of_handle[h]: the region whose pocket holds handle h, -1 for the base layer
    pocket_of_handle = np.full(len(handles), -1, np.int64)
    cover, cell = None, None
    if layered:
        cover, cell = _triangle_cells(tris, regions)
        hidden = _hidden_depths(base_mesh, skeleton, cover)
        pocket_of_handle = _layered_handle_pockets(tri0, hdepth, cover, cell, hidden, name,
                                                   limbs)
    else:
        for r, reg in enumerate(regions):
            in_reg = np.isin(tri0, reg.tris_a)
            if not in_reg.any():
                continue
            hs = np.flatnonzero(in_reg)
            if limbs[r] is not None:    # by bone: the limb's handles on one layer
                pocket_of_handle[hs[_limb_split(hs, hdepth, limbs[r])]] = r
            elif hdepth is not None and np.ptp(hdepth[hs]) > 1e-9:
                d = np.sort(hdepth[hs])
                gap = np.argmax(np.diff(d))
                cut = 0.5 * (d[gap] + d[gap + 1])
                pocket_of_handle[hs[hdepth[hs] > cut]] = r
    dv, vid = cKDTree(X).query(handles)
    pos_in_a = [{int(t): k for k, t in enumerate(reg.tris_a)} for reg in regions]
    for h in range(len(handles)):
        t = int(tri0[h])
        r = int(pocket_of_handle[h])
        if r >= 0:
            t = int(regions[r].tris_b[pos_in_a[r][t]])
        handle_tris[h] = t
        handle_bary[h] = bary0[h]
        if dv[h] < 1e-6:
            v = int(vid[h])
            if r >= 0:
                v = regions[r].pocket_of.get(v, v)
            handle_vertices[h] = v
            tv = tris_all[handle_tris[h]]
            handle_bary[h] = (tv == v).astype(float) if (tv == v).any() else bary0[h]

    def handle_matrix(tris_now, n_now):
        K = len(handles)
        rows = np.repeat(np.arange(K), 3)
        cols = tris_now[handle_tris].ravel()
        return sparse.csr_matrix((handle_bary.ravel(), (rows, cols)), shape=(K, n_now))

    # ---- topology (Secs. 4.3–4.4, Algorithm 1): region by region, cheapest valid b
    if assignments is not None:
        if len(assignments) != len(regions):
            raise ValueError(f"{name}: assignments has {len(assignments)} entries for "
                             f"{len(regions)} occlusion region(s); give one index per region")
        for r, (reg, a) in enumerate(zip(regions, assignments)):
            cands = valid_assignments(reg.n_edges, reg.t_junctions)
            if not 0 <= int(a) < len(cands):
                raise ValueError(f"{name}: assignments[{r}] = {a} but region {r} has "
                                 f"{len(cands)} valid assignments (0..{len(cands) - 1})")
            reg.b, reg.cusp = cands[int(a)]
    elif regions:
        if not target_skeletons:
            raise ValueError(f"{name}: target_skeletons (the poses to deform into) are needed "
                             "to choose the occlusion topology")
        for reg in regions:
            reg.b = valid_assignments(reg.n_edges, reg.t_junctions)[0][0]
        for reg in regions:
            cands = valid_assignments(reg.n_edges, reg.t_junctions)
            scored = {}

            def score(i):
                if i not in scored:
                    b, c = cands[i]
                    reg.b = b
                    t2, nn, copies = incise(tris_all, regions, [g.b for g in regions],
                                            len(X_all))
                    X2 = _expand(X_all, copies)
                    e = _deformation_energy(X2, t2, handle_matrix(t2, len(X2)),
                                            target_skeletons, mu, score_max_iter)
                    scored[i] = e
                    reg.energies.append((b.copy(), c, e))
                return scored[i]

            if len(cands) <= 2 * cusp_scan + 2:
                best = min(range(len(cands)), key=score)
            else:  # odd k: coarse scan of cusp positions, then refine around the best
                step = max(1, len(cands) // (2 * cusp_scan)) * 2
                coarse = list(range(0, len(cands), step)) + list(range(1, len(cands), step))
                best = min(coarse, key=score)
                lo, hi = max(0, best - step - 1), min(len(cands), best + step + 2)
                best = min(range(lo, hi), key=score)
            reg.b, reg.cusp = cands[best][0], cands[best][1]

    tris_f, _, copies = incise(tris_all, regions, [g.b for g in regions], len(X_all))
    X_f = _expand(X_all, copies)
    vertex_layer = np.concatenate([vertex_layer, [vertex_layer[v] if layer == 0 else 1
                                                  for v, layer in copies]]).astype(np.int8)
    handle_vertices_f = np.where(handle_vertices >= 0, tris_f[handle_tris].ravel()[
        np.arange(len(handles)) * 3 + np.argmax(handle_bary, axis=1)], -1)
    final_mesh = TriMesh(X_f, tris_f)

    # ---- depth of layers: BBW weights of the handles × handle depths (Sec. 5.1)
    weights = _handle_weights(X_f, tris_f, handle_vertices_f)
    if regions:
        for reg in regions:
            if hdepth is None:
                reg.depth = np.zeros(2)
                reg.front = "A"
                continue
            vd = weights @ hdepth
            da = vd[np.unique(tris_f[reg.tris_a])].mean()
            db = vd[np.unique(tris_f[reg.tris_b])].mean()
            reg.depth = np.array([da, db])
            reg.front = "A" if da <= db else "B"

    # ---- depth rank of every triangle: 0 visible in the keyframe, k the k-th hidden layer
    rank = np.zeros(len(tris_f), np.int8)
    if layered:
        vd = weights @ hdepth
        pos_in_a = [{int(t): k for k, t in enumerate(reg.tris_a)} for reg in regions]
        for c in np.unique(cell[cover.any(axis=1)]):
            base_c = np.flatnonzero(cell == c)
            stack = [base_c] + [regions[r].tris_b[[pos_in_a[r][int(t)] for t in base_c]]
                                for r in np.flatnonzero(cover[base_c[0]])]
            d = [vd[np.unique(tris_f[tt])].mean() for tt in stack]  # mean layer depth
            for k, i in enumerate(np.argsort(d, kind="stable")):     # ties: listed first
                rank[stack[i]] = k
    else:
        for reg in regions:
            rank[reg.tris_b if reg.front == "A" else reg.tris_a] = 1

    # ---- texture atlas (Sec. 5.1): keyframe on top, the hidden layers below, one band each
    n_bands = int(rank.max())
    tex_coords = X_f[tris_f].copy()
    texture, inpainted = img, 0.0
    hole = np.zeros(((1 + max(n_bands, 1)) * H, W), bool)   # inpainted texels of the atlas
    if n_bands:
        bands, inpainted, holes = _back_texture(
            img, X_f, tris_f, rank, handle_matrix(tris_f, len(X_f)),
            target_skeletons, other_image, other_occlusions, other_mask, mu, inpainter,
            [o.mask_array((H, W)) for o in occlusions])
        texture = np.concatenate([img] + bands, axis=0)
        for k in range(1, n_bands + 1):
            tex_coords[rank == k, :, 1] += k * H
            hole[k * H:(k + 1) * H] = holes[k - 1]
    else:
        texture = np.concatenate([img, np.zeros_like(img)], axis=0)
    return LayeredTemplate(
        mesh=final_mesh, skeleton=skeleton, image=img, mask=mask, handle_tris=handle_tris,
        handle_bary=handle_bary, handle_vertices=handle_vertices_f, layers=tuple(regions),
        regions=regions, vertex_layer=vertex_layer, handle_weights=weights, handle_depth=hdepth,
        texture=texture.astype(np.float32), tex_coords=tex_coords, inpainted_fraction=inpainted,
        occlusions=occlusions, inpainted=hole, layer_rank=rank)


def _triangulate_pslg(outer, polys, points, max_area, min_angle, region_triangles, holes=(),
                      cells=None):
    """Conforming Delaunay triangulation of the foreground outline with the region outlines as
    constrained edges and ``points`` as vertices (Triangle ``pq A a``); each region gets its own
    area bound (about ``region_triangles`` triangles). Overlapping outlines cross (Triangle
    inserts the crossings); then ``cells`` — ``(point (2,), region indices)`` seeds, one per
    piece of the overlap pattern (:func:`_cell_seeds`) — carry the area bounds, the smallest of
    the regions covering the piece."""
    import triangle as tr

    from ..mesh import MIN_PIXEL_AREA, TriMesh, _compact, _orient_positive, default_max_area
    from ..mesh import _point_inside_polygon, polygon_area

    loops = [outer] + list(holes) + list(polys)
    sizes = [len(L) for L in loops]
    starts = np.cumsum([0] + sizes[:-1])
    segments = np.concatenate([s + np.stack([np.arange(m), (np.arange(m) + 1) % m], axis=1)
                               for s, m in zip(starts, sizes)])
    V = np.concatenate(loops + ([points] if len(points) else []))
    if max_area is None:
        max_area = max(default_max_area(abs(polygon_area(outer))), MIN_PIXEL_AREA)
    data = {"vertices": V, "segments": segments}
    if len(holes):
        data["holes"] = np.array([_point_inside_polygon(h) for h in holes])
    if polys:
        bound = [min(max_area, max(abs(polygon_area(P)) / region_triangles, 2.0)) for P in polys]
        if cells is None:
            data["regions"] = np.array([[*_point_inside_polygon(P), r + 1, bound[r]]
                                        for r, P in enumerate(polys)])
        else:
            data["regions"] = np.array([[*pt, c + 1, min(bound[r] for r in rs)]
                                        for c, (pt, rs) in enumerate(cells)])
    area_str = np.format_float_positional(float(max_area), trim="-")
    angle_str = np.format_float_positional(float(min_angle), trim="-")
    opts = f"pq{angle_str}a{area_str}" + ("Aa" if polys else "") + "Q"
    out = tr.triangulate(data, opts)
    X = np.asarray(out["vertices"], dtype=np.float64)
    tris = np.asarray(out["triangles"], dtype=np.int64)
    X, tris = _compact(X, tris)
    return TriMesh(X, _orient_positive(X, tris))


def _cell_seeds(region_masks, min_depth=1.5):
    """One seed point per connected piece of the regions' overlap pattern (pixels covered by
    the same set of regions): ``[(point (2,) px, region indices), …]``, the point the piece's
    pixel farthest from its edge (pieces thinner than ``min_depth`` px are left out)."""
    from scipy import ndimage

    code = np.zeros(region_masks[0].shape, np.int64)
    for r, m in enumerate(region_masks):
        code |= m.astype(np.int64) << r
    out = []
    for c in np.unique(code[code > 0]):
        comps, k = ndimage.label(code == c)
        for i in range(1, k + 1):
            dist = ndimage.distance_transform_edt(comps == i)
            if dist.max() < min_depth:
                continue
            y, x = np.unravel_index(np.argmax(dist), dist.shape)
            out.append((np.array([x, y], float),
                        tuple(r for r in range(len(region_masks)) if (c >> r) & 1)))
    return out


def _deformation_energy(X, tris, B, target_skeletons, mu, max_iter=None):
    """``E_d + E_pose`` (Eq. 1) of the template deformed through ``target_skeletons`` (each
    solve warm-started from the previous, large moves split, as :func:`deform_sequence`), each
    solve capped at ``max_iter`` iterations (the energy only falls with more: a capped wrong
    topology still scores high)."""
    from .deform import SymmetricDirichletDeformer, deform_through

    opts = {} if max_iter is None else {"max_iter": int(max_iter)}
    return float(deform_through(SymmetricDirichletDeformer(X, tris, B, mu=mu),
                                target_skeletons, **opts).energy)


def _handle_weights(X, tris, handle_vertices):
    """(n, K) bounded biharmonic weights of the handles on the (non-manifold) layered mesh
    (libigl ``bbw``, Jacobson et al. 2011); handles that are not vertices get a zero column,
    handles sharing a vertex share its column."""
    import igl

    K = len(handle_vertices)
    use = np.flatnonzero(handle_vertices >= 0)
    b, first = np.unique(handle_vertices[use], return_index=True)
    hs = use[first]
    bc = np.zeros((len(b), len(b)))
    bc[np.arange(len(b)), np.arange(len(b))] = 1.0
    Wb = np.asarray(igl.bbw(X, tris, b.astype(np.int64), bc, partition_unity=False,
                            max_iter=50), dtype=float)
    Wb = np.clip(Wb, 0, 1)
    Wb /= np.maximum(Wb.sum(1, keepdims=True), 1e-12)
    W = np.zeros((len(X), K))
    W[:, hs] = Wb
    # handles sharing a vertex share its weight column
    for h in use:
        if h not in hs:
            W[:, h] = W[:, hs[np.searchsorted(b, handle_vertices[h])]]
    return W / np.maximum(W.sum(1, keepdims=True), 1e-12)


def _telea(rgba, hole):
    import cv2

    rgb = np.clip(rgba[..., :3] * 255, 0, 255).astype(np.uint8)
    out = cv2.inpaint(rgb, hole.astype(np.uint8), 5, cv2.INPAINT_TELEA)
    res = rgba.copy()
    res[..., :3] = np.where(hole[..., None], out / 255.0, rgba[..., :3])
    res[..., 3] = np.where(hole, 1.0, rgba[..., 3])
    return res


def _back_texture(img, X, tris, rank, B, target_skeletons, other_image,
                  other_occlusions, other_mask, mu, inpainter, own_occ_masks):
    """Texture of the hidden layers in the keyframe's frame (Sec. 5.1), one band per depth rank.

    Where a hidden triangle, deformed into the other key's pose, lands fully on the other key's
    foreground and outside its occlusion regions, its texture comes from the other key; the
    rest of the hidden layers' area is inpainted. The ``k``-th hidden layer (``rank == k``)
    covers the pixels of at least ``k`` of this key's occlusion masks (with two layers, their
    union). Returns (textures: list of (H, W, 4) float32 per rank 1, 2, …, inpainted fraction
    of the hidden layers' area, holes: list of (H, W) bool, the inpainted pixels per rank)."""
    from scipy import ndimage

    from ..render import warp_texture
    from .deform import SymmetricDirichletDeformer, deform_through

    H, W = img.shape[:2]
    count = np.zeros((H, W), np.int64)
    for m in own_occ_masks:
        count += m
    x = None
    if other_image is not None and target_skeletons:
        other = as_rgba_float(other_image, "other_image")
        omask = other_mask if other_mask is not None else classical_foreground_mask(other)
        occ = np.zeros((H, W), bool)
        for o in other_occlusions or ():
            occ |= o.mask_array((H, W))
        ok_px = ndimage.binary_erosion(omask, iterations=1) & ~ndimage.binary_dilation(occ, iterations=2)
        x = deform_through(SymmetricDirichletDeformer(X, tris, B, mu=mu), target_skeletons).x
    texs, holes, n_hole, n_cov = [], [], 0, 0
    for k in range(1, int(rank.max()) + 1):
        # the k-th hidden layer covers k occlusion regions of this key (in rest position)
        covered = count >= k
        hole = covered.copy()
        tex = img.copy()
        if x is not None:
            bt = tris[rank == k]
            ij = np.clip(np.round(x[bt][..., ::-1]).astype(int), 0, [H - 1, W - 1])
            good = ok_px[ij[..., 0], ij[..., 1]].all(axis=1)
            if good.any():
                # the other key pulled back onto the rest positions of the good triangles
                pulled = warp_texture(other, x, X, bt[good], (H, W))
                got = pulled[..., 3] > 0.5
                tex = np.where((got & covered)[..., None], pulled, tex)
                hole &= ~got
        n_hole, n_cov = n_hole + hole.sum(), n_cov + covered.sum()
        tex = (inpainter or _telea)(tex, hole) if hole.any() else tex
        texs.append(tex.astype(np.float32))
        holes.append(hole)
    return texs, float(n_hole / max(n_cov, 1)), holes


# ------------------------------------------------------------------ suggestions, warnings
def limb_overlaps(skeleton, radius=None, skip_adjacent=True):
    """Pairs of non-adjacent bones whose capsules (radius ``radius`` px, default 2.5 % of the
    skeleton's height) overlap in 2D: where limbs may occlude each other.

    Returns list of ``(joint_a, joint_b)`` name pairs, each bone named by its end joint.
    """
    xy = skeleton.xy
    bones = skeleton.bones
    if radius is None:
        radius = 0.025 * max(np.ptp(xy[:, 1]), np.ptp(xy[:, 0]), 1.0)
    out = []
    for i in range(len(bones)):
        for j in range(i + 1, len(bones)):
            a, b = bones[i], bones[j]
            if skip_adjacent and len(set(a.tolist()) & set(b.tolist())):
                continue
            if skip_adjacent and (skeleton.parents[a[0]] in b or skeleton.parents[b[0]] in a):
                continue
            d = _segment_distance(xy[a[0]], xy[a[1]], xy[b[0]], xy[b[1]])
            if d < 2 * radius:
                out.append((skeleton.names[a[1]], skeleton.names[b[1]]))
    return out


def _segment_distance(p0, p1, q0, q1):
    if _segments_cross(p0, p1, q0, q1):
        return 0.0
    d_p = _project_on_segments([p0, p1], q0[None], q1[None])[1]
    d_q = _project_on_segments([q0, q1], p0[None], p1[None])[1]
    return float(min(d_p.min(), d_q.min()))


def _capsule_distance(P, a, b):
    """Distance of points ``P`` (..., 2) to the segment ``a → b``."""
    ab = np.asarray(b, float) - np.asarray(a, float)
    t = np.clip(((P - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(P - (a + t[..., None] * ab), axis=-1)


def _bone_of(skeleton, joint, where):
    try:
        j = skeleton.index(joint)
    except (KeyError, ValueError, IndexError):
        raise ValueError(f"{where}: unknown joint {joint!r} (bones are named by their end "
                         f"joint, one of {list(skeleton.names)})") from None
    if skeleton.parents[j] < 0:
        raise ValueError(f"{where}: {joint!r} is the root; it ends no bone")
    return skeleton.xy[[skeleton.parents[j], j]]


def _bone_depth(skeleton, joint):
    j = skeleton.index(joint)
    return float(np.mean(skeleton.depth[[skeleton.parents[j], j]]))


def _front_bones(skeleton, bones, front):
    """The occluder's bones among ``bones`` (see :func:`suggest_t_junctions`)."""
    if front is None:
        if skeleton.depth is not None:
            d = {j: _bone_depth(skeleton, j) for j in bones}
            mid = np.mean(list(d.values()))
            front = [j for j in bones if d[j] < mid - 1e-9]
        if not front:
            def level(j):
                n, i = 0, skeleton.index(j)
                while skeleton.parents[i] >= 0:
                    i, n = skeleton.parents[i], n + 1
                return n
            front = [max(bones, key=level)]
    front = list(dict.fromkeys(front))
    if not front or not set(front) < set(bones):
        raise ValueError(f"front must be a non-empty proper subset of bones {bones}, got "
                         f"{front}")
    return front


def _check_region_args(region, mask, radius, bones, skeleton):
    R = np.asarray(region)
    fg = np.asarray(mask)
    if R.ndim != 2 or not R.any():
        raise ValueError(f"region must be a non-empty (H, W) bool mask, got shape {R.shape}")
    if fg.shape != R.shape:
        raise ValueError(f"mask must have the region's shape {R.shape}, got {fg.shape}")
    if isinstance(radius, bool) or not np.isfinite(radius) or radius <= 0:
        raise ValueError(f"radius must be a positive number of px, got {radius!r}")
    if isinstance(bones, str):
        raise ValueError(f"bones must be a sequence of joint names, got the string {bones!r}")
    bones = list(dict.fromkeys(bones))
    if len(bones) < 2:
        raise ValueError(f"bones must name at least two distinct bones, got {bones}")
    for j in bones:
        _bone_of(skeleton, j, "bones")
    return R.astype(bool), fg.astype(bool), bones


def suggest_t_junctions(region, skeleton, bones, radius, mask, front=None, min_run=4,
                        widths=None):
    """Suggested T-junctions of one suggested occlusion region — a CPU substitute for the
    user's clicks (Sec. 4.1), like :func:`suggest_occlusions` is for the mask network.

    Heuristic. A suggested region is the overlap of limb capsules inside the foreground, so
    every point of its outline is there because one of three things ends: the **occluder's**
    capsule (the *front* bones; outside it the occluded part is visible — its layer continues,
    the occluder's is cut), the occluded part's capsule, or the foreground silhouette (outside
    them the occluder continues over the occluded part or over the paper). A T-junction is where
    the outline switches between the first kind and the others — where the front limb's
    silhouette meets the other part's outline, in a drawing the place where that outline ends
    against the occluder (Fig. 7). Each outline point (the region's marching-squares contour) is
    labelled by the nearest of the three boundaries (|capsule distance − ``radius``| for the
    unions of front and back capsules, the Euclidean distance to the foreground's edge), runs
    shorter than ``min_run`` points are absorbed (:func:`switch_points`, the same rule as the
    true T-junctions of :func:`~physlab.inbetween.characters.character_occlusions`), and the
    switch points lie on the region's outline. Their number is even, so the region has the
    two topologies of an even ``k`` — but now they differ along the outline instead of being
    "one layer sewn all round". The capsules only approximate the limbs' silhouettes, so the
    points are as good as ``radius`` matches the limbs' width.

    Parameters
    ----------
    region : (H, W) bool, the region's mask (non-empty).
    skeleton : Skeleton, the key's pose; ``depth`` (if given) picks the front bones.
    bones : sequence of joint names, each naming the bone it ends (>= 2 distinct bones).
    radius : float > 0, capsule radius (px), as used for the suggestion.
    mask : (H, W) bool, the key's foreground.
    front : subset of ``bones``: the occluder's bones; default the bones nearer than the mean
        depth of ``bones`` (by :attr:`Skeleton.depth`), without depths (or all at one depth)
        the one bone farthest from the root in the hierarchy (a hand on the chest).
    min_run : int ≥ 1, shortest run (contour points ≈ px) that counts.
    widths : None or dict joint name → capsule radius (px) of the bone it ends, as passed to
        :func:`suggest_occlusions` (bones it lacks keep ``radius``).

    Returns
    -------
    (k, 2) float pixel points ``(x, y)`` on the region's outline, ``k`` even (possibly 0).

    Raises
    ------
    ValueError for an empty or mis-shaped region or mask, unknown joints, fewer than two
    bones, a bad radius, ``front`` not a proper non-empty subset of ``bones``.
    """
    from scipy import ndimage
    from skimage.measure import find_contours

    R, fg, bones = _check_region_args(region, mask, radius, bones, skeleton)
    seg = {j: _bone_of(skeleton, j, "bones") for j in bones}
    front = _front_bones(skeleton, bones, front)
    back = [j for j in bones if j not in front]
    if isinstance(min_run, bool) or not isinstance(min_run, (int, np.integer)) or min_run < 1:
        raise ValueError(f"min_run must be an int >= 1, got {min_run!r}")

    contour = max(find_contours(np.pad(R, 1).astype(float), 0.5), key=len)
    yx = contour[:-1] - 1.0
    xy = yx[:, ::-1]
    r = _check_widths(widths, skeleton)

    def outline_distance(js):  # |distance to the union of the capsules' outlines|
        return np.abs(np.min([_capsule_distance(xy, *seg[j]) - r.get(j, radius) for j in js],
                             axis=0))

    d_front, d_back = outline_distance(front), outline_distance(back)
    # distance to the silhouette: inside, to the nearest background pixel centre minus ½ px
    edt = ndimage.distance_transform_edt(fg) - 0.5
    ij = np.clip(np.round(yx).astype(int), 0, np.array(R.shape) - 1)
    d_fg = np.maximum(edt[ij[:, 0], ij[:, 1]], 0.0)
    on_front = d_front < np.minimum(d_back, d_fg)
    return switch_points(xy, on_front, int(min_run))


def suggest_occlusions(image, skeleton, radius=None, mask=None, predictor=None,
                       t_junctions=False, widths=None, extent="capsule", pairs=None, up=False,
                       by_limb=False):
    """Suggested occlusion regions of a keyframe: the CPU substitute for the paper's mask
    network (Sec. 4.1), for the user to accept or edit.

    For every pair of non-adjacent bones whose capsules (radius ``radius`` px) overlap in 2D,
    the overlap of the two capsules inside the foreground is one region; joint depths (if the
    skeleton has them) pick the occluder, otherwise the template finds the topology (Sec. 4.3)
    and depths the front layer. With ``t_junctions=False`` (the default) the regions carry no
    T-junctions (the paper asks the user for them); with ``t_junctions=True`` each carries
    :func:`suggest_t_junctions` — where the occluder's capsule outline meets the other outlines
    on the region's boundary, also a CPU heuristic. ``predictor``
    (``(image, skeleton) -> list of Occlusion``) replaces the heuristic with a learned one.

    ``widths`` (dict joint name → px, e.g. :func:`bone_widths` of a drawing of the same
    character whose limbs are free, such as its rest pose) gives each bone its own capsule
    radius, the half-width the limb is drawn with; bones it lacks keep ``radius``. With them a
    forearm across the belly suggests the forearm's whole width over the belly's, up to the
    body's outline, instead of the overlap of two thin capsules (limbs drawn inside the body
    have no silhouette of their own to measure, hence the other drawing). ``radius`` still
    decides which bones overlap (:func:`limb_overlaps`).

    ``extent="contact"`` grows each region to the limb's whole contact with the body
    (:func:`limb_contact` with ``up=False``: the overlapping bone and the bones below it, e.g.
    forearm and hand): of the two bones the one deeper in the hierarchy is the limb, its
    capsule overlaps with all partners are the seed, and the region is the limb's pixels along
    the axis intervals where the drawing is wider than the limb, cut across the limb where it
    leaves the body's outline — one region per limb (labels joined by ``"+"``), with
    :func:`limb_contact`'s T-junctions when ``t_junctions=True``. A limb with no such contact
    keeps its capsule overlaps. ``up=True`` grows the region along the whole limb
    (:func:`limb_contact` with ``up=True``: the upper arm too). ``by_limb=True`` records the
    limb's bones on the region (:attr:`Occlusion.limb`), so that
    :func:`build_layered_template` keeps the limb's handles on one layer (by bone) instead of
    splitting the region's handles at their largest depth gap. ``pairs`` (iterable of
    bone-name pairs) keeps only those of :func:`limb_overlaps`' pairs (e.g. a limb on the body
    that the drawing does not have). ``up`` and ``by_limb`` are for ``extent="contact"``.

    Returns list of :class:`Occlusion` (labels ``"<joint a>/<joint b>"``, bones named by their
    end joints).

    Raises
    ------
    ValueError naming the argument for a bad ``t_junctions``, ``mask``, ``widths``, ``extent``,
    ``pairs``, ``up`` or ``by_limb`` (``up=True`` or ``by_limb=True`` with ``extent="capsule"``).
    """
    if predictor is not None:
        return list(predictor(image, skeleton))
    if not isinstance(t_junctions, (bool, np.bool_)):
        raise ValueError(f"t_junctions must be True or False, got {t_junctions!r}")
    img = as_rgba_float(image)
    H, W = img.shape[:2]
    fg = classical_foreground_mask(img) if mask is None else np.asarray(mask, bool)
    if fg.shape != (H, W):
        raise ValueError(f"mask must have the image's shape {(H, W)}, got {fg.shape}")
    if radius is None:
        radius = 0.06 * max(np.ptp(skeleton.xy[:, 1]), np.ptp(skeleton.xy[:, 0]), 1.0)
    r = _check_widths(widths, skeleton)
    if not isinstance(extent, str) or extent not in REGION_EXTENTS:
        raise ValueError(f"extent must be one of {REGION_EXTENTS}, got {extent!r}")
    for arg, v in (("up", up), ("by_limb", by_limb)):
        if not isinstance(v, (bool, np.bool_)):
            raise ValueError(f"{arg} must be True or False, got {v!r}")
        if v and extent != "contact":
            raise ValueError(f"{arg}=True is for extent='contact' (a limb's region), got "
                             f"extent={extent!r}")
    overlaps = limb_overlaps(skeleton, radius)
    if pairs is not None:
        try:
            keep = {frozenset(p) for p in pairs}
        except TypeError:
            raise ValueError(f"pairs must be an iterable of (joint, joint) bone pairs, got "
                             f"{pairs!r}") from None
        if any(len(p) != 2 for p in keep):
            raise ValueError(f"pairs must hold pairs of two distinct joint names, got {pairs!r}")
        for p in keep:
            for j in p:
                _bone_of(skeleton, j, "pairs")
        overlaps = [o for o in overlaps if frozenset(o) in keep]
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    P = np.stack([xx, yy], axis=-1)

    caps = {}

    def capsule(joint):  # each bone's capsule once, though it may overlap several bones
        if joint not in caps:
            j = skeleton.index(joint)
            caps[joint] = (_capsule_distance(P, *skeleton.xy[[skeleton.parents[j], j]])
                           < r.get(joint, radius))
        return caps[joint]

    out = []
    for ja, jb in overlaps:
        m = capsule(ja) & capsule(jb) & fg
        if m.sum() >= 16:
            tj = (suggest_t_junctions(m, skeleton, (ja, jb), radius, fg, widths=r)
                  if t_junctions else ())
            out.append(Occlusion(m, tj, label=f"{ja}/{jb}"))
    if extent == "capsule":
        return out
    return _contact_regions(out, skeleton, fg, radius, r, t_junctions, up, by_limb)


def _contact_regions(capsule_regions, skeleton, fg, radius, widths, t_junctions, up=False,
                     by_limb=False):
    """:func:`suggest_occlusions`' ``extent="contact"``: the capsule overlaps grouped by their
    limb (the bone of each pair deeper in the hierarchy) and grown by :func:`limb_contact`
    (``up`` as there); returns list of :class:`Occlusion` (a limb without contact keeps its
    capsule regions), with ``limb`` the bones the region was grown along when ``by_limb``."""
    def level(j):
        n, i = 0, skeleton.index(j)
        while skeleton.parents[i] >= 0:
            i, n = skeleton.parents[i], n + 1
        return n

    groups = {}
    for o in capsule_regions:
        ja, jb = o.label.split("/")
        limb = ja if level(ja) >= level(jb) else jb
        groups.setdefault(limb, []).append(o)
    out = []
    for limb, regs in groups.items():
        seed = np.any([o.mask for o in regs], axis=0)
        # by default the limb's bone and the bones below it only (up=False): with the upper
        # arm in the region too, the layered run of a forearm folded back across the chest
        # (AnimatedDrawings char1, zombie) explodes (handle error 36 px), with the handles
        # split by depth gap or by bone (by_limb: 42 px) alike (docs/occlusion_experiments.md)
        region, tj = limb_contact(skeleton, limb, fg, widths.get(limb, radius), seed=seed,
                                  up=up)
        if not region.any():
            out += regs
            continue
        chain = limb_chain(skeleton, limb)
        if not up:
            chain = chain[chain.index(limb):]
        out.append(Occlusion(region, tj if t_junctions else (),
                             label="+".join(o.label for o in regs),
                             limb=tuple(chain) if by_limb else ()))
    return out


def bone_widths(skeleton, mask, percentile=50.0, samples=24):
    """Half-width (px) each bone is drawn with: the foreground's distance to its outline along
    the bone's middle 60 % (``samples`` points; the ``percentile`` of the values inside the
    foreground). Measure it on a drawing whose limbs are free — a rest pose, or the other key
    — and pass it to :func:`suggest_occlusions` as ``widths``.

    Returns dict joint name → half-width (px, ≥ 1), one entry per bone (named by its end
    joint).
    """
    from scipy import ndimage

    fg = np.asarray(mask)
    if fg.ndim != 2 or fg.dtype != bool or not fg.any():
        raise ValueError(f"mask must be a non-empty (H, W) bool array, got "
                         f"{fg.dtype} {fg.shape}")
    if isinstance(percentile, bool) or not isinstance(percentile, (int, float, np.number)) \
            or not 0 <= percentile <= 100:
        raise ValueError(f"percentile must be in [0, 100], got {percentile!r}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 2:
        raise ValueError(f"samples must be an int >= 2, got {samples!r}")
    edt = ndimage.distance_transform_edt(fg)
    H, W = fg.shape
    s = np.linspace(0.2, 0.8, int(samples))[:, None]
    out = {}
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            continue
        a, b = skeleton.xy[p], skeleton.xy[j]
        ij = np.clip(np.round((a + s * (b - a))[:, ::-1]).astype(int), 0, [H - 1, W - 1])
        v = edt[ij[:, 0], ij[:, 1]]
        v = v[v > 0]
        out[skeleton.names[j]] = max(float(np.percentile(v, percentile)), 1.0) if len(v) else 1.0
    return out


def _check_widths(widths, skeleton):
    """``widths`` as a dict joint → positive px (empty for None), validated."""
    if widths is None:
        return {}
    if not isinstance(widths, dict):
        raise ValueError(f"widths must be a dict joint name -> px (e.g. bone_widths(...)), got "
                         f"{type(widths).__name__}")
    for j, v in widths.items():
        _bone_of(skeleton, j, "widths")
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) \
                or not np.isfinite(v) or v <= 0:
            raise ValueError(f"widths[{j!r}] must be a positive number of px, got {v!r}")
    return {j: float(v) for j, v in widths.items()}


# -------------------------------------------------------------- contact of a limb (regions)
#: Suggested region extents of :func:`suggest_occlusions`: the overlap of two capsules, or the
#: limb's whole contact with the wider drawing under it (:func:`limb_contact`).
REGION_EXTENTS = ("capsule", "contact")


def limb_chain(skeleton, joint):
    """The limb a bone belongs to: the bones from the limb's root to its tip, through ``joint``.

    Bones are named by their end joint. From ``joint``'s bone the chain goes up through the
    parent bone while neither of that bone's joints has another child and its start joint is
    not the skeleton's root (it stops below a branching joint: chest, pelvis, torso), and down
    through single children to the tip. For a forearm (``"left_hand"``, elbow → hand) this is
    upper arm + forearm (+ hand bones), for a shin thigh + shin (+ foot); a bone that starts
    at a branching joint and has none below it (the chest) is a chain of one.

    Parameters
    ----------
    skeleton : Skeleton. joint : str, a non-root joint name (the bone it ends).

    Returns
    -------
    list of joint names, proximal to distal, each naming the bone it ends.

    Raises
    ------
    ValueError naming ``joint`` for an unknown joint or the root.
    """
    _bone_of(skeleton, joint, "joint")
    parents = np.asarray(skeleton.parents)
    n_child = np.bincount(parents[parents >= 0], minlength=len(parents))
    j = skeleton.index(joint)
    chain = [j]
    while True:   # up: bone p = (q, p) joins while neither p nor q branches (q no root)
        p = parents[chain[0]]
        q = parents[p] if p >= 0 else -1
        if q < 0 or parents[q] < 0 or n_child[p] != 1 or n_child[q] != 1:
            break
        chain.insert(0, p)
    while n_child[chain[-1]] == 1:   # down through single children
        chain.append(int(np.flatnonzero(parents == chain[-1])[0]))
    return [skeleton.names[i] for i in chain]


def _chain_coordinates(P, polyline):
    """Distance of points ``P`` (..., 2) to a polyline (n, 2) and the arclength (px) of their
    nearest point on it: ``(d (...), s (...), length)``."""
    A, B = polyline[:-1], polyline[1:]
    L = np.linalg.norm(B - A, axis=1)
    s0 = np.r_[0.0, np.cumsum(L)]
    d = np.full(P.shape[:-1], np.inf)
    s = np.zeros(P.shape[:-1])
    for a, b, l, start in zip(A, B, L, s0):
        ab = b - a
        t = np.clip(((P - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
        dk = np.linalg.norm(P - (a + t[..., None] * ab), axis=-1)
        closer = dk < d
        d = np.where(closer, dk, d)
        s = np.where(closer, start + t * l, s)
    return d, s, float(s0[-1])


def limb_contact(skeleton, joint, mask, width, seed=None, ratio=1.0, min_run=4, up=True):
    """The whole contact of a limb with what it is drawn over: a suggested occlusion region
    reaching the body's outline where the limb crosses it, with its T-junctions.

    Heuristic (a CPU stand-in for the paper's mask network and the user's clicks, Sec. 4.1).
    The limb is :func:`limb_chain` of ``joint``'s bone (``up=False``: from that bone down),
    drawn as a capsule of half-width ``width`` around its bones. Along the limb's axis (1 px steps) the foreground's distance to
    its outline (a distance transform of ``mask``) is the limb's own half-width where the limb
    is free, and more where it lies over something wider — the body. The axis intervals where
    that distance exceeds ``ratio · width`` are the contact; the interval(s) that meet ``seed``
    (e.g. the capsule overlap of :func:`suggest_occlusions`) are kept, and the region is the
    foreground within ``width`` of the axis whose nearest axis point lies in them: cut square
    across the limb where the limb leaves the body's outline, not at the end of a capsule.

    T-junctions: each point of the region's outline is labelled "occluder" where it lies on the
    limb's capsule outline (distance to the axis ≥ ``width`` − 1.5 px; the limb's sides and its
    tip), "other" inside it (a cut across the limb where it leaves the body, the foreground
    silhouette) and on the cap of the limb's root joint (the limb stays attached there); the
    T-junctions are where the label switches (:func:`switch_points`, runs shorter than
    ``min_run`` absorbed): the corners where the limb's outline enters or leaves the body.

    Parameters
    ----------
    skeleton : Skeleton (pixels). joint : str, a limb bone (named by its end joint).
    mask : (H, W) bool, the key's foreground.
    width : float > 0, the limb's half-width (px).
    seed : None or (H, W) bool; None keeps every contact interval.
    ratio : float > 0, how much wider than ``width`` the drawing must be to count as contact.
    min_run : int ≥ 1, shortest run of outline points (≈ px) that counts.
    up : bool, the whole :func:`limb_chain` (default) or only ``joint``'s bone and the bones
        below it (the limb's root cap is then the bone's start joint, e.g. the elbow).

    Returns
    -------
    ``(region (H, W) bool, t_junctions (k, 2) float (x, y), k even)``; an all-False region and
    no T-junctions when the limb touches nothing (or no contact meets ``seed``).

    Raises
    ------
    ValueError naming the argument for an unknown joint, a bad mask, seed, width, ratio,
    min_run or up.
    """
    from scipy import ndimage
    from skimage.measure import find_contours

    fg = np.asarray(mask)
    if fg.ndim != 2 or fg.dtype != bool or not fg.any():
        raise ValueError(f"mask must be a non-empty (H, W) bool array, got {fg.dtype} "
                         f"{fg.shape}")
    for arg, v in (("width", width), ("ratio", ratio)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) \
                or not np.isfinite(v) or v <= 0:
            raise ValueError(f"{arg} must be a positive number, got {v!r}")
    if isinstance(min_run, bool) or not isinstance(min_run, (int, np.integer)) or min_run < 1:
        raise ValueError(f"min_run must be an int >= 1, got {min_run!r}")
    if seed is not None:
        seed = np.asarray(seed)
        if seed.shape != fg.shape or seed.dtype != bool:
            raise ValueError(f"seed must be None or a (H, W) bool array of the mask's shape "
                             f"{fg.shape}, got {seed.dtype} {seed.shape}")
    if not isinstance(up, (bool, np.bool_)):
        raise ValueError(f"up must be True or False, got {up!r}")
    chain = limb_chain(skeleton, joint)
    if not up:
        chain = chain[chain.index(joint):]
    ids = [skeleton.index(j) for j in chain]
    poly = skeleton.xy[[skeleton.parents[ids[0]]] + ids].astype(float)     # (n + 1, 2)
    H, W = fg.shape
    empty = (np.zeros((H, W), bool), np.zeros((0, 2)))
    # the drawing's half-width along the limb's axis
    edt = ndimage.distance_transform_edt(fg)
    _, _, length = _chain_coordinates(poly[:1], poly)
    if length < 1.0:
        return empty
    s_ax = np.arange(0.0, length + 0.5, 1.0)
    seg = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))]
    axis = np.stack([np.interp(s_ax, seg, poly[:, 0]), np.interp(s_ax, seg, poly[:, 1])], 1)
    ij = np.round(axis[:, ::-1]).astype(int)
    inside = (ij >= 0).all(1) & (ij < [H, W]).all(1)
    half = np.zeros(len(s_ax))
    half[inside] = edt[ij[inside, 0], ij[inside, 1]]
    touch = half > ratio * float(width)
    if not touch.any():
        return empty
    # contact intervals [s_a, s_b] along the axis
    edges = np.flatnonzero(np.diff(np.r_[0, touch.astype(np.int8), 0]))
    runs = [(s_ax[a], s_ax[b - 1]) for a, b in zip(edges[::2], edges[1::2])]
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    d, s, _ = _chain_coordinates(np.stack([xx, yy], axis=-1), poly)
    near = fg & (d < width)
    if seed is not None:
        if not (seed & near).any():
            return empty
        ss = s[seed & near]
        runs = [(a, b) for a, b in runs if b >= ss.min() - 1.0 and a <= ss.max() + 1.0]
        if not runs:
            return empty
    region = near & np.any([(s >= a - 0.5) & (s <= b + 0.5) for a, b in runs], axis=0)
    if seed is not None:
        region |= seed
    # keep the component(s) touching the seed (or all)
    lab, n = ndimage.label(region)
    if n > 1:
        keep = np.unique(lab[seed & region]) if seed is not None else np.arange(1, n + 1)
        region = np.isin(lab, keep[keep > 0])
    if region.sum() < 16:
        return empty
    contour = max(find_contours(np.pad(region, 1).astype(float), 0.5), key=len)
    yx = contour[:-1] - 1.0
    dc, sc, _ = _chain_coordinates(yx[:, ::-1], poly)
    on_limb = (dc >= width - 1.5) & (sc > 0.5)     # the limb's sides and tip, not its root cap
    return region, switch_points(yx[:, ::-1], on_limb, int(min_run))
