"""Cut-out ("paper-doll") animation of a drawing: body parts cut free and moved rigidly.

The oldest model of a moving drawing (Reiniger's silhouette films, cut-out TV animation,
bone rigs without mesh deformation): the rest drawing is cut into body parts, each part moves
by the rigid transform that takes its bones from the rest skeleton to the new pose, and the
parts are painted back to front by depth. A limb that swings in front of the body covers it
cleanly — no sheet is stretched between them. It is the opposite modelling assumption to the
one elastic sheet of Brodt & Bessmeltsev 2024 (Sec. 4.2, Eq. 1), which is why
:class:`~physlab.inbetween.evaluate.OccludedDrawingPair` offers it as a second ground truth
(``truth="parts"``) beside the posed sheet.

**Parts** (:func:`part_bones`): one per bone, except that the AnimatedDrawings trunk is one
piece — the spine, both shoulder bones and both hip bones form the ``torso``, which follows the
spine and shoulders exactly (the BVH retarget moves them as one rigid body; the pelvis sways a
few degrees against them, :data:`UNFITTED_BONES`) — and the neck bone carries the ``head``;
``*_elbow``/``*_hand``/``*_knee``/``*_foot`` bones are the ``*_upper_arm``, ``*_forearm``
(with the hand), ``*_thigh``, ``*_shin`` (with the foot). Zero-length bones (root → hip) carry
nothing.

**Segmentation** (:func:`segment_parts`): every foreground pixel goes to the part whose bone
*box* is nearest — the signed distance to the rectangle along the bone, as wide as the bone is
drawn (:func:`~physlab.inbetween.occlusion.bone_widths`), cut flat at its joints (a leaf bone's
far end is round, so the hand beyond the wrist joint stays with the forearm). Measuring to the
box instead of the bone's axis keeps the body's pixels with the wide torso when a thin arm is
drawn against it, and the flat cut at the shoulder keeps the arm's root with the arm. Each
part then keeps its largest connected piece; stray islands go to the nearest other part.

**Joints** (:func:`joint_caps`): parts cut along a line at a joint open a wedge on the outside
of a bend. Each part therefore also carries a *cap*: its parent part's pixels within radius
``r`` of the joint they share (``r`` = the 90th percentile distance from the joint to the cut
between the two, + 1 px, at most :data:`CAP_LIMIT` of the part's bone length), moved with the
part: about the limb's half-width, so the cap is a disc across the limb at the joint. The cap
is painted just below the farther of the two parts, so it only shows where neither covers the
joint — it fills the wedge with a rounded elbow/knee and never draws over either part.

**Seams**: away from the joints, parts that abut in the drawing (an arm drawn against the
body) are cut along a line too; every part is drawn :data:`SEAM_OVERLAP` px wider into its
neighbours, so the antialiased edges of two parts that stay together overlap instead of
leaving a light hairline between them.

**Painting** (:func:`render_cutout`): every part (and cap) is warped with its rigid transform
(inverse mapping, bilinear, premultiplied alpha) and composited back to front by its depth,
the mean of its joints' depths (:attr:`~physlab.inbetween.Skeleton.depth`, smaller =
nearer; painter's order as Sec. 5.1). At the rest pose every transform is the identity and
the drawing is reproduced to float precision.

Units: pixels, ``(x, y)`` with y down, pixel ``image[i, j]`` centred at ``(j, i)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .skeleton import MIN_BONE_LENGTH, Skeleton, check_compatible

__all__ = ["CutoutParts", "part_bones", "segment_parts", "joint_caps", "part_transforms",
           "part_depths", "cutout_layers", "render_cutout"]

#: Smallest half-width (px) of a bone box (a stick figure's one-pixel strokes).
MIN_HALF_WIDTH = 1.5
#: Pixels every part is grown into its neighbours: abutting parts overlap by this much, so
#: their antialiased edges leave no light hairline where the cut runs (the rest drawing is
#: unchanged: the overlap repeats the neighbour's own pixels).
SEAM_OVERLAP = 1
#: Largest joint cap radius, as a fraction of the part's (longest) bone.
CAP_LIMIT = 0.75
#: Trunk bones the trunk carries but does not follow: the BVH sways the pelvis a few degrees
#: against the spine; the cut-out trunk moves with the spine and shoulders (exactly), the
#: thighs hang from the posed hip joints and their caps cover the few pixels of difference.
UNFITTED_BONES = ("_hip",)
#: Limb bone suffix → part name suffix (the bone into ``*_elbow`` is the upper arm, ...).
LIMB_PARTS = {"_elbow": "_upper_arm", "_hand": "_forearm", "_knee": "_thigh", "_foot": "_shin"}


@dataclass(frozen=True, eq=False)
class CutoutParts:
    """A drawing cut into body parts (:func:`segment_parts`).

    Attributes
    ----------
    names : tuple of P str, part names.
    bones : tuple of P int arrays, the joints whose bones (``parent(j) → j``) make up each part.
    labels : (H, W) int, the part of every foreground pixel (index into ``names``), −1 off it.
    parent : (P,) int, the part each part hangs from (−1 for the root part).
    joint : (P,) int, the joint a part shares with its parent (−1 for the root part).
    caps : (P, H, W) bool, the parent's pixels each part carries over its joint
        (:func:`joint_caps`; all False for the root part).
    cap_radius : (P,) float, the caps' radii (px, 0 for the root part).
    """

    names: tuple
    bones: tuple
    labels: np.ndarray
    parent: np.ndarray
    joint: np.ndarray
    caps: np.ndarray
    cap_radius: np.ndarray

    def mask(self, k):
        """(H, W) bool, the pixels of part ``k`` (index or name)."""
        k = self.names.index(k) if isinstance(k, str) else int(k)
        return self.labels == k

    def drawn(self, k):
        """(H, W) bool, the pixels part ``k`` is drawn with: its own grown by
        :data:`SEAM_OVERLAP` px into the neighbouring parts (never into the background)."""
        from scipy import ndimage

        m = self.mask(k)
        if SEAM_OVERLAP > 0:
            m = ndimage.binary_dilation(m, structure=np.ones((3, 3)),
                                        iterations=SEAM_OVERLAP) & (self.labels >= 0)
        return m


def _part_name(skeleton, j):
    from .retarget import _base_name

    base = _base_name(skeleton.names[j])
    if base == "torso" or base.endswith(("_shoulder", "_hip")):
        return "torso"
    if base == "neck":
        return "head" if not np.any(skeleton.parents == j) else "neck"
    name = skeleton.names[j]
    for end, part in LIMB_PARTS.items():
        if base.endswith(end):  # left_elbow2 -> left_upper_arm2
            return base[:-len(end)] + part + name[len(base):]
    return skeleton.names[j]


def part_bones(skeleton):
    """Group the skeleton's bones into body parts (module docstring, "Parts").

    Parameters
    ----------
    skeleton : Skeleton (pixels), the rest pose.

    Returns
    -------
    dict part name → (m,) int array of joints whose bones (``parent(j) → j``) it carries, in
    the order of first appearance in ``skeleton.order``; zero-length bones are left out.
    """
    if not isinstance(skeleton, Skeleton):
        raise TypeError(f"skeleton must be a Skeleton, got {type(skeleton).__name__}")
    live = skeleton.bone_lengths() > MIN_BONE_LENGTH
    out = {}
    for j in skeleton.order:
        if skeleton.parents[j] >= 0 and live[j]:
            out.setdefault(_part_name(skeleton, j), []).append(int(j))
    if not out:
        raise ValueError("skeleton has no bone of positive length: nothing to cut parts along")
    return {k: np.array(v) for k, v in out.items()}


def _box_sdf(P, a, b, w, round_end):
    """(n,) signed distance of points P (n, 2) to the box along segment a → b of half-width
    w, flat at a, flat (or round, ``round_end``) at b; negative inside."""
    d = b - a
    L = np.linalg.norm(d)
    e = d / L
    q = P - a
    u = q @ e                                     # along the bone
    v = np.abs(q[:, 0] * e[1] - q[:, 1] * e[0])   # across it
    dx, dy = np.maximum(-u, u - L), v - w
    box = np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)
    if round_end:
        box = np.where(u > L, np.linalg.norm(P - b, axis=1) - w, box)
    return box


def segment_parts(mask, skeleton, widths=None, caps=True):
    """Cut a drawing's foreground into body parts (module docstring, "Segmentation").

    Parameters
    ----------
    mask : (H, W) bool foreground of the drawing in its rest pose.
    skeleton : Skeleton (pixels) of that rest pose.
    widths : dict joint name → half-width (px) of the bone into it, default
        :func:`~physlab.inbetween.occlusion.bone_widths` of ``mask``; at least
        :data:`MIN_HALF_WIDTH`.
    caps : bool, give every part its joint cap (:func:`joint_caps`); False: none (to show
        the gaps they fill).

    Returns
    -------
    CutoutParts.

    Raises
    ------
    ValueError for a mask that is not a non-empty (H, W) bool array, or widths that are not
    positive numbers of known joints.
    """
    from scipy import ndimage

    from .occlusion import _check_widths, bone_widths

    fg = np.asarray(mask)
    if fg.ndim != 2 or fg.dtype != bool or not fg.any():
        raise ValueError(f"mask must be a non-empty (H, W) bool array, got {fg.dtype} "
                         f"{fg.shape}")
    if not isinstance(caps, (bool, np.bool_)):
        raise ValueError(f"caps must be True or False, got {caps!r}")
    groups = part_bones(skeleton)
    w = bone_widths(skeleton, fg) if widths is None else _check_widths(widths, skeleton)
    names = tuple(groups)
    yx = np.argwhere(fg)                                       # (n, 2) foreground pixels
    P = yx[:, ::-1].astype(float)                              # (n, 2) as (x, y)
    has_child = np.bincount(skeleton.parents[skeleton.parents >= 0], minlength=len(skeleton))
    score = np.full((len(P), len(names)), np.inf)
    for k, js in enumerate(groups.values()):
        for j in js:
            a, b = skeleton.xy[skeleton.parents[j]], skeleton.xy[j]
            hw = max(float(w.get(skeleton.names[j], MIN_HALF_WIDTH)), MIN_HALF_WIDTH)
            score[:, k] = np.minimum(score[:, k], _box_sdf(P, a, b, hw, has_child[j] == 0))
    labels = np.full(fg.shape, -1)
    labels[yx[:, 0], yx[:, 1]] = np.argmin(score, axis=1)
    # every part keeps its largest connected piece; the rest goes to the nearest other part
    stray = np.zeros(fg.shape, bool)
    for k in range(len(names)):
        comp, n = ndimage.label(labels == k, structure=np.ones((3, 3)))
        if n > 1:
            keep = 1 + int(np.argmax(np.bincount(comp.ravel())[1:]))
            stray |= (comp > 0) & (comp != keep)
    if stray.any():
        _, (ii, jj) = ndimage.distance_transform_edt(~((labels >= 0) & ~stray),
                                                     return_indices=True)
        labels[stray] = labels[ii[stray], jj[stray]]
    parent, joint = _part_tree(skeleton, groups, labels)
    cap, radius = joint_caps(labels, skeleton, groups, parent, joint) if caps else \
        (np.zeros((len(names), *fg.shape), bool), np.zeros(len(names)))
    return CutoutParts(names, tuple(groups.values()), labels, parent, joint, cap, radius)


def _part_tree(skeleton, groups, labels):
    """(parent (P,), joint (P,)): the part each part hangs from and the joint they share.

    A part's joint is the start of its bone nearest the root; its parent is the part of the
    bone into that joint (through zero-length bones). Parts that reach the root this way hang
    from the root part — the torso, else the part with most pixels."""
    names = list(groups)
    owner = {int(j): k for k, js in enumerate(groups.values()) for j in js}
    depth = np.zeros(len(skeleton), int)
    for j in skeleton.order:
        if skeleton.parents[j] >= 0:
            depth[j] = depth[skeleton.parents[j]] + 1
    root = names.index("torso") if "torso" in names else \
        int(np.argmax(np.bincount(labels[labels >= 0], minlength=len(names))))
    parent, joint = np.full(len(names), -1), np.full(len(names), -1)
    for k, js in enumerate(groups.values()):
        if k == root:
            continue
        j0 = int(skeleton.parents[js[np.argmin(depth[js])]])
        joint[k], up = j0, j0
        while up >= 0 and up not in owner:
            up = int(skeleton.parents[up])
        parent[k] = owner.get(up, root)
        if parent[k] == k:
            parent[k] = root
    return parent, joint


def joint_caps(labels, skeleton, groups, parent, joint):
    """The cap of every part (module docstring, "Joints").

    Parameters
    ----------
    labels : (H, W) int part labels (−1 background). skeleton : rest Skeleton.
    groups : :func:`part_bones`. parent, joint : (P,) int, :func:`segment_parts`' part tree.

    Returns
    -------
    (caps (P, H, W) bool, radius (P,) float px).
    """
    from scipy import ndimage

    H, W = labels.shape
    yy, xx = np.mgrid[:H, :W]
    caps = np.zeros((len(groups), H, W), bool)
    radius = np.zeros(len(groups))
    lengths = skeleton.bone_lengths()
    for k, js in enumerate(groups.values()):
        if parent[k] < 0:
            continue
        c = skeleton.xy[joint[k]]
        dist = np.hypot(xx - c[0], yy - c[1])
        par = labels == parent[k]
        seam = par & ndimage.binary_dilation(labels == k, structure=np.ones((3, 3)))
        r_max = CAP_LIMIT * float(lengths[js].max())
        r = np.percentile(dist[seam], 90) + 1.0 if seam.any() else MIN_HALF_WIDTH
        radius[k] = float(np.clip(r, MIN_HALF_WIDTH, max(r_max, MIN_HALF_WIDTH)))
        caps[k] = par & (dist <= radius[k])
    return caps, radius


def _kabsch_2d(X, x):
    """Rigid transform (2, 3) taking points X (m, 2) to x (m, 2) in the least-squares sense."""
    cX, cx = X.mean(0), x.mean(0)
    A, B = X - cX, x - cx
    dot = np.einsum("md,md->", A, B)
    cross = np.sum(A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0])
    th = np.arctan2(cross, dot) if abs(dot) + abs(cross) > 0 else 0.0
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return np.concatenate([R, (cx - R @ cX)[:, None]], axis=1)


def part_transforms(parts, rest, skeleton):
    """Rigid transform of every part: the best rotation + translation (2D Kabsch) taking its
    bones' joints from ``rest`` to ``skeleton`` (exact for bones that keep their length).

    Returns (P, 2, 3) float64 ``[R | t]``: ``x = R X + t``.
    """
    check_compatible(rest, skeleton, ("rest", "skeleton"))
    from .retarget import _base_name

    out = np.empty((len(parts.names), 2, 3))
    for k, js in enumerate(parts.bones):
        fit = [j for j in js if not _base_name(rest.names[j]).endswith(UNFITTED_BONES)]
        js = np.array(fit) if fit else js
        ids = np.unique(np.concatenate([js, rest.parents[js]]))
        out[k] = _kabsch_2d(rest.xy[ids], skeleton.xy[ids])
    return out


def part_depths(parts, skeleton):
    """(P,) depth of every part: the mean depth of its bones' joints (0 without depths)."""
    if skeleton.depth is None:
        return np.zeros(len(parts.names))
    return np.array([skeleton.depth[np.unique(np.concatenate([js, skeleton.parents[js]]))]
                     .mean() for js in parts.bones])


def _pixel_grid(shape):
    """(H·W, 2) float (x, y) of every pixel of an image of ``shape``, row by row."""
    yy, xx = np.mgrid[:shape[0], :shape[1]].astype(float)
    return np.stack([xx.ravel(), yy.ravel()], 1)


def _warp(layer, T, shape, grid):
    """Premultiplied layer (h, w, 4) moved by the rigid T (2, 3) into an image of ``shape``
    whose pixels are ``grid`` (:func:`_pixel_grid`)."""
    from scipy import ndimage

    H, W = shape
    R, t = T[:, :2], T[:, 2]
    X = (grid - t) @ R  # Rᵀ (x − t) for every row: the rest position of each output pixel
    out = np.empty((H, W, 4), np.float64)
    for c in range(4):
        out[..., c] = ndimage.map_coordinates(layer[..., c], [X[:, 1], X[:, 0]], order=1,
                                              mode="constant", cval=0.0).reshape(H, W)
    return np.clip(out, 0.0, 1.0)


def cutout_layers(image, parts, rest, skeleton, out_shape=None):
    """The warped parts and caps in painting order (back to front).

    Parameters
    ----------
    image : (H, W, 4) uint8 or float RGBA (or (H, W, 3)), the rest drawing; its pixels off
        ``parts.labels`` are not drawn.
    parts : CutoutParts of that drawing (:func:`segment_parts`).
    rest : Skeleton, the rest pose the parts were cut at. skeleton : Skeleton, the new pose
        (its ``depth`` orders the parts; without depths they keep the order of ``parts``).
    out_shape : (H, W) of the output, default the drawing's.

    Returns
    -------
    list of ``(name, kind ("part" or "cap"), depth, layer (H, W, 4) float premultiplied
    RGBA)``, back to front; caps sit just below the farther of their part and its parent.
    """
    from .template import as_rgba_float

    img = as_rgba_float(image)
    if img.shape[:2] != parts.labels.shape:
        raise ValueError(f"image is {img.shape[:2]} but the parts were cut from a "
                         f"{parts.labels.shape} drawing")
    shape = img.shape[:2] if out_shape is None else tuple(out_shape)
    T = part_transforms(parts, rest, skeleton)
    depth = part_depths(parts, skeleton)
    items = []  # (depth key, 0 cap / 1 part, index, ...)
    for k, name in enumerate(parts.names):
        for kind, m in (("part", parts.drawn(k)), ("cap", parts.caps[k])):
            if not m.any():
                continue
            a = img[..., 3] * m
            layer = np.concatenate([img[..., :3] * a[..., None], a[..., None]], axis=-1)
            key = depth[k] if kind == "part" else max(depth[k], depth[parts.parent[k]])
            items.append((-key, kind == "part", k, name, kind, key, layer))
    items.sort(key=lambda it: it[:3])   # far to near; at equal depth caps first
    grid = _pixel_grid(shape)           # once for every layer
    return [(name, kind, key, _warp(layer, T[k], shape, grid))
            for _, _, k, name, kind, key, layer in items]


def render_cutout(image, parts, rest, skeleton, out_shape=None):
    """The drawing posed as a cut-out: :func:`cutout_layers` composited back to front
    ("over", premultiplied).

    Returns (H, W, 4) float32 straight RGBA in [0, 1].
    """
    layers = cutout_layers(image, parts, rest, skeleton, out_shape)
    out = np.zeros_like(layers[0][3]) if layers else None
    for *_, layer in layers:
        out = layer + out * (1.0 - layer[..., 3:])
    a = out[..., 3:]
    rgb = np.divide(out[..., :3], a, out=np.zeros_like(out[..., :3]), where=a > 1e-12)
    return np.concatenate([rgb, a], axis=-1).astype(np.float32)
