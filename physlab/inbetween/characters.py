"""Procedural cartoon characters with ground-truth skeletons, for evaluating inbetweening.

Skeleton-driven inbetweening (Brodt & Bessmeltsev 2024) gets two drawn keyframes, their 2D
skeletons and the skeletal motion ``x_i(t)`` between them, and must draw the frames in
between. To *measure* how well it does we need the true inbetweens, so this module draws a
character from its skeleton: :func:`render_character` paints a humanoid at any pose of
:func:`character_skeleton`, and :class:`InbetweenPair` renders the ground truth at
``physlab.inbetween.interpolate(skeleton0, skeleton1, t, method="local_angles")``. An
inbetweener sees only :meth:`InbetweenPair.keyframes`, the two skeletons and
:meth:`InbetweenPair.animation`. (Being the local-angle blend by construction, these pairs
cannot rank interpolation schemes; :func:`physlab.inbetween.evaluate.interpolation_pairs` has
pairs whose in-between poses come from motion capture.)

The character
-------------
16 joints named like the AnimatedDrawings skeletons (``left`` is the character's left, i.e.
the right of the image; the character faces the viewer)::

    pelvis (root) ─ chest ─ neck ─ head_top
                    chest ─ left_shoulder ─ left_elbow ─ left_hand      (same for right_)
    pelvis ─ left_hip ─ left_knee ─ left_foot                           (same for right_)

and 15 rigid parts (:data:`CHARACTER_PARTS`), each attached to one bone (the bone into
joint ``j`` is the segment ``parent(j) → j``, as in :class:`~physlab.inbetween.Skeleton`):

============== ============================== ===============================================
part           bone                           shape
============== ============================== ===============================================
torso          pelvis → chest                 rounded polygon (shirt, belt, trousers)
neck           chest → neck                   capsule
head           neck → head_top                ellipse + ears + hair tuft, with a face
*_upper_arm    *_shoulder → *_elbow           tapered capsule
*_forearm      *_elbow → *_hand               tapered capsule
*_hand         end of the forearm bone        glove (ellipse + thumb)
*_thigh        *_hip → *_knee                 tapered capsule
*_shin         *_knee → *_foot                tapered capsule
*_foot         end of the shin bone           shoe pointing outwards
============== ============================== ===============================================

The clavicle bones (chest → shoulders) and hip bones (pelvis → hips) carry no part of their
own: they are inside the torso.

Every part is painted in its **local frame**: ``a`` along its bone (from the bone's start,
scaled by rest length / current length, so a stretched bone stretches its part and texture)
and ``b`` across it (mirrored on the right side so the character is symmetric). Shapes,
textures, shading and the face are functions of ``(a, b)`` only, so a part's texture moves
rigidly with it, and colours and pattern phases depend on ``seed`` and ``style`` only, never on
the pose: the same character at two poses is consistent.

Overlaps at joints: layered, like a paper puppet. Parts are painted back to front, each with
its own ink outline, parents over children (:data:`PAINT_ORDER`): feet under shins under
thighs, hands under forearms under upper arms, all limbs and the neck under the torso, the
head on top. So at a joint the parent's rounded end (with its outline) covers the child's
round end, e.g. the upper arm's elbow cap lies on the forearm, and the torso's edge covers the
tops of the upper arms and thighs.

Units: pixels, ``(x, y)`` with y down; pixel ``image[i, j]`` is centred at ``(j, i)``; angles
in degrees in the public API, positive = clockwise on screen (the :class:`Skeleton`
convention, ``atan2(dy, dx)`` with y down).
"""
from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

from physlab.paint import INK
from physlab.paint import fill as _fill
from physlab.paint import polygon_sdf as _polygon_sdf

from . import skeleton as _skeleton

if TYPE_CHECKING:
    from .skeleton import Skeleton


__all__ = [
    "CHARACTER_STYLES",
    "CHARACTER_JOINTS",
    "CHARACTER_PARTS",
    "ADJACENT_PARTS",
    "PAINT_ORDER",
    "character_skeleton",
    "pose_character",
    "render_character",
    "character_part_labels",
    "part_overlaps",
    "paint_order",
    "character_occlusions",
    "character_layered_occlusions",
    "InbetweenPair",
    "inbetween_benchmark",
    "occlusion_benchmark",
    "occlusion_benchmark_three_layers",
]

#: Visual styles of :func:`render_character`:
#: "flat" — flat colours, thick ink, polka-dot shirt, banded trousers;
#: "shaded" — cylinder/sphere shading with highlights, striped shirt, dotted trousers; the
#: light is fixed in each part's frame (from the upper left at rest) so the shading moves with
#: the part like a texture;
#: "patterned" — flat colours, medium ink, checked shirt, hatched trousers;
#: "sketchy" — pale fills, thin doubled ink lines, hatched shadows, sailor stripes, cross-hatching.
CHARACTER_STYLES = ("flat", "shaded", "patterned", "sketchy")

#: Joint names, in the order of :func:`character_skeleton` (AnimatedDrawings-like naming).
CHARACTER_JOINTS = ("pelvis", "chest", "neck", "head_top",
                    "right_shoulder", "right_elbow", "right_hand",
                    "left_shoulder", "left_elbow", "left_hand",
                    "right_hip", "right_knee", "right_foot",
                    "left_hip", "left_knee", "left_foot")
_PARENT_NAMES = {"pelvis": None, "chest": "pelvis", "neck": "chest", "head_top": "neck",
                 "right_shoulder": "chest", "right_elbow": "right_shoulder",
                 "right_hand": "right_elbow", "left_shoulder": "chest",
                 "left_elbow": "left_shoulder", "left_hand": "left_elbow",
                 "right_hip": "pelvis", "right_knee": "right_hip", "right_foot": "right_knee",
                 "left_hip": "pelvis", "left_knee": "left_hip", "left_foot": "left_knee"}
_PARENTS = np.array([-1 if _PARENT_NAMES[n] is None else CHARACTER_JOINTS.index(_PARENT_NAMES[n])
                     for n in CHARACTER_JOINTS], dtype=np.int64)

# Rest pose in "design pixels" (a 512 px image is _UNIT_512 image px per design px):
# joint → (bone length, local angle in degrees relative to the parent bone; bones out of the
# root are measured from the +x axis). Arms held out 25° below horizontal, legs 12° apart.
_REST = {"pelvis": (0.0, 0.0), "chest": (110.0, -90.0), "neck": (26.0, 0.0),
         "head_top": (80.0, 0.0),
         "right_shoulder": (46.0, -90.0), "right_elbow": (62.0, -25.0),
         "right_hand": (58.0, -8.0),
         "left_shoulder": (46.0, 90.0), "left_elbow": (62.0, 25.0), "left_hand": (58.0, 8.0),
         "right_hip": (24.0, 180.0), "right_knee": (80.0, -78.0), "right_foot": (76.0, -6.0),
         "left_hip": (24.0, 0.0), "left_knee": (80.0, 78.0), "left_foot": (76.0, 6.0)}
#: image px per design px at size 512: the rest figure is 70 % of the image height.
_UNIT_512 = 0.7 * 512 / 404.0
#: design-px offset (down) of the pelvis from the image centre, centring the figure vertically
#: (the hair tuft reaches 228 design px above the pelvis, the soles 176 below).
_PELVIS_DY = (228.0 - 176.0) / 2

# --------------------------------------------------------------------------- parts
# name → (joint whose bone carries it, anchored at bone "start" or "end", kind)
_PART_SPECS = {
    "torso": ("chest", "start", "torso"),
    "neck": ("neck", "start", "neck"),
    "head": ("head_top", "start", "head"),
    "right_upper_arm": ("right_elbow", "start", "upper_arm"),
    "right_forearm": ("right_hand", "start", "forearm"),
    "right_hand": ("right_hand", "end", "hand"),
    "left_upper_arm": ("left_elbow", "start", "upper_arm"),
    "left_forearm": ("left_hand", "start", "forearm"),
    "left_hand": ("left_hand", "end", "hand"),
    "right_thigh": ("right_knee", "start", "thigh"),
    "right_shin": ("right_foot", "start", "shin"),
    "right_foot": ("right_foot", "end", "foot"),
    "left_thigh": ("left_knee", "start", "thigh"),
    "left_shin": ("left_foot", "start", "shin"),
    "left_foot": ("left_foot", "end", "foot"),
}
#: Part names (order of :func:`character_part_labels` indices).
CHARACTER_PARTS = tuple(_PART_SPECS)
#: Back-to-front painting order: parents over children, the head on top.
PAINT_ORDER = ("right_foot", "left_foot", "right_shin", "left_shin", "right_thigh", "left_thigh",
               "right_hand", "left_hand", "right_forearm", "left_forearm",
               "right_upper_arm", "left_upper_arm", "neck", "torso", "head")
#: Pairs of parts that share a joint and may overlap there; any other pair must stay apart
#: (:func:`part_overlaps`).
ADJACENT_PARTS = frozenset(frozenset(p) for p in [
    ("torso", "neck"), ("neck", "head"),
    ("torso", "right_upper_arm"), ("right_upper_arm", "right_forearm"),
    ("right_forearm", "right_hand"),
    ("torso", "left_upper_arm"), ("left_upper_arm", "left_forearm"), ("left_forearm", "left_hand"),
    ("torso", "right_thigh"), ("right_thigh", "right_shin"), ("right_shin", "right_foot"),
    ("torso", "left_thigh"), ("left_thigh", "left_shin"), ("left_shin", "left_foot"),
])

# Shape constants (design px). Capsules: (r_start, r_end); lengths are the rest bone lengths.
_CAPSULES = {"neck": (11.0, 11.0), "upper_arm": (14.0, 12.0), "forearm": (12.0, 10.0),
             "thigh": (19.0, 15.0), "shin": (15.0, 12.0)}
_CAPSULE_BONE = {"neck": "neck", "upper_arm": "left_elbow", "forearm": "left_hand",
                 "thigh": "left_knee", "shin": "left_foot"}
# torso: polygon in (a, b), rounded by _TORSO_ROUND
_TORSO_POLY = np.array([[-14.0, -36.0], [50.0, -27.0], [98.0, -40.0], [110.0, -33.0],
                        [110.0, 33.0], [98.0, 40.0], [50.0, 27.0], [-14.0, 36.0],
                        [-21.0, 0.0]])
_TORSO_ROUND = 10.0
_BELT = (6.0, 18.0)  # a-range of the belt on the torso
_HEAD = (38.0, 0.0, 44.0, 40.0)  # centre a, b; semi-axes along, across
# local bounding boxes (a0, a1, b0, b1) in design px (a relative to the anchor, unscaled)
_EXTENTS = {"torso": (-33.0, 122.0, -52.0, 52.0), "neck": (-11.0, 37.0, -11.0, 11.0),
            "head": (-8.0, 98.0, -52.0, 52.0), "upper_arm": (-14.0, 76.0, -14.0, 14.0),
            "forearm": (-12.0, 70.0, -12.0, 12.0), "hand": (-8.0, 32.0, -24.0, 17.0),
            "thigh": (-19.0, 99.0, -19.0, 19.0), "shin": (-15.0, 91.0, -15.0, 15.0),
            "foot": (-6.0, 25.0, -43.0, 17.0)}
_MIN_SIZE = 64

# --------------------------------------------------------------------------- looks
_SKIN = [(0.99, 0.85, 0.72), (0.93, 0.74, 0.57), (0.78, 0.56, 0.40), (0.56, 0.38, 0.26),
         (1.00, 0.87, 0.45)]
_SHIRT = [(0.88, 0.22, 0.22), (0.20, 0.48, 0.88), (0.28, 0.70, 0.36), (0.97, 0.74, 0.16),
          (0.60, 0.36, 0.80), (0.98, 0.55, 0.22), (0.18, 0.70, 0.72)]
_ACCENT = [(0.99, 0.97, 0.88), (0.99, 0.90, 0.30), (0.15, 0.22, 0.45), (0.98, 0.62, 0.75)]
_PANTS = [(0.20, 0.29, 0.56), (0.42, 0.30, 0.20), (0.27, 0.27, 0.31), (0.52, 0.72, 0.90),
          (0.40, 0.53, 0.28)]
_SHOES = [(0.78, 0.14, 0.16), (0.30, 0.21, 0.16), (0.20, 0.34, 0.70), (0.95, 0.93, 0.88)]
_HAIR = [(0.22, 0.15, 0.11), (0.58, 0.33, 0.14), (0.96, 0.80, 0.36), (0.78, 0.30, 0.13),
         (0.14, 0.14, 0.20)]
_INK_WIDTH = {"flat": 5.5, "shaded": 4.0, "patterned": 3.2, "sketchy": 2.6}  # px at size 512
_LIGHT = np.array([-0.6, -0.8])  # world light direction at rest (from the upper left), y down


def _unit(size):
    """Image px per design px for an image of ``size`` px."""
    return size / 512 * _UNIT_512


def _check_size(size):
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise TypeError(f"size must be an int (pixels), got {type(size).__name__}")
    size = int(size)
    if size < _MIN_SIZE:
        raise ValueError(f"size must be >= {_MIN_SIZE} px (the ink and the face need room), "
                         f"got {size}")
    return size


def _check_style(style):
    if style not in CHARACTER_STYLES:
        raise ValueError(f"unknown style {style!r}; choose one of {CHARACTER_STYLES}")
    return style


def _check_skeleton(skeleton, size, what="skeleton"):
    """ValueError unless ``skeleton`` has the character's topology and lies in the image."""
    if not isinstance(skeleton, _skeleton.Skeleton):
        raise TypeError(f"{what} must be a physlab.inbetween.Skeleton, got "
                        f"{type(skeleton).__name__}")
    if skeleton.names != CHARACTER_JOINTS or not np.array_equal(skeleton.parents, _PARENTS):
        raise ValueError(f"{what} must have the topology of character_skeleton() (joints "
                         f"{list(CHARACTER_JOINTS)} with their parents); got joints "
                         f"{list(skeleton.names)} with parents {skeleton.parents.tolist()}. "
                         "Make poses with pose_character(character_skeleton(size), ...).")
    out = np.any((skeleton.xy < 0) | (skeleton.xy > size - 1), axis=1)
    if out.any():
        j = int(np.flatnonzero(out)[0])
        raise ValueError(f"{what}: joint {skeleton.names[j]!r} at {tuple(skeleton.xy[j].round(1))} "
                         f"is outside the {size}×{size} image; use a skeleton made for this size "
                         f"(character_skeleton(size={size})) or move it inside")


# --------------------------------------------------------------------------- skeleton
def character_skeleton(size=512):
    """The character's rest skeleton: arms out 25° below horizontal, legs apart.

    The figure (head top to soles) fills 70 % of the image height, centred.

    Parameters
    ----------
    size : int ≥ 64, the image is ``size × size`` px.

    Returns
    -------
    Skeleton with the 16 joints :data:`CHARACTER_JOINTS`, ``xy`` (16, 2) float px (y down).
    """
    size = _check_size(size)
    u = _unit(size)
    lengths = np.array([_REST[n][0] for n in CHARACTER_JOINTS]) * u
    angles = np.deg2rad([_REST[n][1] for n in CHARACTER_JOINTS])
    root = np.array([(size - 1) / 2, (size - 1) / 2 + _PELVIS_DY * u])
    return _skeleton.Skeleton.from_local(CHARACTER_JOINTS, _PARENTS, root, angles, lengths)


#: part name → the joint whose bone ``pose_character`` rotates for it.
_POSE_BONES = {"torso": "chest", "neck": "neck", "head": "head_top",
               "right_clavicle": "right_shoulder", "left_clavicle": "left_shoulder",
               "right_upper_arm": "right_elbow", "right_forearm": "right_hand",
               "left_upper_arm": "left_elbow", "left_forearm": "left_hand",
               "right_thigh": "right_knee", "right_shin": "right_foot",
               "left_thigh": "left_knee", "left_shin": "left_foot"}


def pose_character(rest, offset=(0.0, 0.0), rotation=0.0, stretch=None, **angles_deg):
    """A pose made by rotating the character's bones relative to ``rest`` (forward kinematics).

    Each keyword rotates one part's bone about its start joint by that many **degrees,
    positive = clockwise on screen**; the parts below it follow (local angles are relative to
    the parent bone, :meth:`Skeleton.from_local`). Keywords: ``torso`` (bends the whole upper
    body about the pelvis), ``neck``, ``head``, ``left_clavicle``/``right_clavicle``
    (shrug), ``left_upper_arm``, ``left_forearm`` (the hand follows), ``left_thigh``,
    ``left_shin`` (the foot follows), and the same with ``right_``. On screen the left arm
    is on the right, so e.g. ``left_upper_arm=-60`` raises it and ``right_upper_arm=+60``
    raises the other one.

    Parameters
    ----------
    rest : Skeleton with the topology of :func:`character_skeleton` (any pose).
    offset : (2,) px, translation of the root (pelvis).
    rotation : degrees, rotation of the whole body about the pelvis (clockwise on screen).
    stretch : optional dict part name (as the keywords) → factor multiplying its bone length
        (squash and stretch; the part and its texture scale along the bone).
    **angles_deg : part name → degrees.

    Returns
    -------
    Skeleton, same names and parents.
    """
    if not isinstance(rest, _skeleton.Skeleton) or rest.names != CHARACTER_JOINTS \
            or not np.array_equal(rest.parents, _PARENTS):
        raise ValueError("rest must be a Skeleton with the topology of character_skeleton()")
    stretch = {} if stretch is None else dict(stretch)
    for key in list(angles_deg) + list(stretch):
        if key not in _POSE_BONES:
            hint = (" (hands and feet are rigid with the forearm / shin: rotate those)"
                    if key.endswith(("_hand", "_foot")) else "")
            raise ValueError(f"unknown part {key!r}{hint}; pose_character rotates "
                             f"{sorted(_POSE_BONES)}")
    ang = rest.local_angles().copy()
    lengths = rest.bone_lengths().copy()
    for key, deg in angles_deg.items():
        ang[CHARACTER_JOINTS.index(_POSE_BONES[key])] += np.deg2rad(float(deg))
    for key, f in stretch.items():
        if not f > 0:
            raise ValueError(f"stretch factors must be > 0, got {key}={f}")
        lengths[CHARACTER_JOINTS.index(_POSE_BONES[key])] *= float(f)
    root_children = np.flatnonzero(_PARENTS == 0)
    ang[root_children] += np.deg2rad(float(rotation))
    root = rest.xy[rest.root] + np.asarray(offset, dtype=float)
    return _skeleton.Skeleton.from_local(CHARACTER_JOINTS, _PARENTS, root, ang, lengths)


# --------------------------------------------------------------------------- geometry
def _sd_capsule(a, b, r0, r1, h):
    """SDF of a tapered capsule from (0, 0) radius r0 to (h, 0) radius r1 (iq's uneven capsule)."""
    px, py = np.abs(b), a
    s = (r0 - r1) / h
    c = np.sqrt(1.0 - s * s)
    k = -s * px + c * py
    return np.where(k < 0, np.hypot(px, py) - r0,
                    np.where(k > c * h, np.hypot(px, py - h) - r1, c * px + s * py - r0))


def _sd_ellipse(a, b, ca, cb, ra, rb):
    """Approximate SDF of an axis-aligned ellipse (first order, zero exactly on the ellipse)."""
    pa, pb = a - ca, b - cb
    k0 = np.hypot(pa / ra, pb / rb)
    k1 = np.hypot(pa / ra ** 2, pb / rb ** 2)
    return np.where(k1 > 1e-9, k0 * (k0 - 1.0) / np.maximum(k1, 1e-9), -min(ra, rb))


def _sd_segment(a, b, a0, b0, a1, b1):
    """Distance to the segment (a0, b0)–(a1, b1)."""
    ea, eb = a1 - a0, b1 - b0
    t = np.clip(((a - a0) * ea + (b - b0) * eb) / (ea * ea + eb * eb), 0.0, 1.0)
    return np.hypot(a - a0 - t * ea, b - b0 - t * eb)


def _shape_sdf(kind, a, b):
    """SDF (design px) of a part of ``kind`` at local coordinates ``a``, ``b`` (design px)."""
    if kind in _CAPSULES:
        r0, r1 = _CAPSULES[kind]
        return _sd_capsule(a, b, r0, r1, _REST[_CAPSULE_BONE[kind]][0])
    if kind == "torso":

        return _polygon_sdf(SimpleNamespace(x=a, y=b), _TORSO_POLY) - _TORSO_ROUND
    if kind == "head":
        ca, cb, ra, rb = _HEAD
        d = _sd_ellipse(a, b, ca, cb, ra, rb)
        ears = np.minimum(_sd_ellipse(a, b, 36.0, 40.0, 11.0, 8.0),
                          _sd_ellipse(a, b, 36.0, -40.0, 11.0, 8.0))
        tuft = np.minimum(_sd_ellipse(a, b, 83.0, -10.0, 9.0, 12.0),
                          _sd_ellipse(a, b, 84.0, -28.0, 7.0, 9.0))
        return np.minimum(np.minimum(d, ears), tuft)
    if kind == "hand":
        palm = _sd_ellipse(a, b, 14.0, 1.0, 16.0, 14.0)
        thumb = _sd_ellipse(a, b, 6.0, -15.0, 9.5, 7.0)
        return np.minimum(palm, thumb)
    if kind == "foot":
        toe = _sd_ellipse(a, b, 11.0, -14.0, 12.0, 27.0)
        heel = np.hypot(a - 8.0, b - 3.0) - 12.0
        return np.minimum(toe, heel)
    raise AssertionError(kind)


@dataclass(frozen=True)
class _PartFrame:
    """Where one part sits in the image: local coords of pixel p are
    a = (p - origin)·axis / (k u), b = mirror (p - origin)·normal / u (design px)."""

    name: str
    kind: str
    origin: np.ndarray  # (2,) px
    axis: np.ndarray  # (2,) unit vector along the bone
    normal: np.ndarray  # (2,) unit vector, axis rotated by +90° (on screen: clockwise)
    mirror: float  # -1 on the right side, +1 elsewhere
    k: float  # current / rest bone length (1 for hands and feet)
    u: float  # image px per design px
    box: tuple  # (y0, y1, x0, x1) pixel slice bounds, possibly empty

    def coords(self):
        """Local coords ``a``, ``b`` (design px), each (y1 - y0, x1 - x0), over the box."""
        y0, y1, x0, x1 = self.box
        dx = np.arange(x0, x1, dtype=np.float64)[None, :] - self.origin[0]
        dy = np.arange(y0, y1, dtype=np.float64)[:, None] - self.origin[1]
        a = (dx * self.axis[0] + dy * self.axis[1]) / (self.k * self.u)
        b = (dx * self.normal[0] + dy * self.normal[1]) * (self.mirror / self.u)
        return a, b

    def sdf(self, a, b):
        """Part SDF in image px (approximate where the bone is stretched)."""
        return _shape_sdf(self.kind, a, b) * (self.u * min(self.k, 1.0))


def _part_frames(skeleton, size):
    """One :class:`_PartFrame` per part of ``CHARACTER_PARTS`` for a (validated) skeleton."""
    u = _unit(size)
    xy = skeleton.xy
    ang = skeleton.bone_angles()
    L = skeleton.bone_lengths()
    frames = []
    for name, (joint, anchor, kind) in _PART_SPECS.items():
        j = CHARACTER_JOINTS.index(joint)
        axis = np.array([np.cos(ang[j]), np.sin(ang[j])])
        normal = np.array([-axis[1], axis[0]])
        mirror = -1.0 if name.startswith("right_") else 1.0
        if anchor == "start":
            origin, k = xy[_PARENTS[j]], max(L[j] / (_REST[joint][0] * u), 0.05)
        else:
            origin, k = xy[j], 1.0
        a0, a1, b0, b1 = _EXTENTS[kind]
        corners = np.array([origin + axis * (aa * k * u) + normal * (mirror * bb * u)
                            for aa in (a0, a1) for bb in (b0, b1)])
        lo = np.floor(corners.min(axis=0) - 1.5).astype(int)
        hi = np.ceil(corners.max(axis=0) + 2.5).astype(int)
        x0, y0 = np.clip(lo, 0, size)
        x1, y1 = np.clip(hi, 0, size)
        frames.append(_PartFrame(name, kind, origin, axis, normal, mirror, k, u,
                                 (int(y0), int(max(y1, y0)), int(x0), int(max(x1, x0)))))
    return frames


def _rest_light():
    """part name → (la, lb): the world light direction in each part's rest frame."""
    rest = character_skeleton(512)
    out = {}
    for f in _part_frames(rest, 512):
        out[f.name] = (float(_LIGHT @ f.axis), float(f.mirror * (_LIGHT @ f.normal)))
    return out


# --------------------------------------------------------------------------- patterns (SDFs)
def _sd_dots(a, b, period, radius, pa, pb):
    """Hexagonal lattice of dots (SDF, design px), phase (pa, pb)."""
    row_h = period * 0.866
    r = np.floor((a - pa) / row_h)
    ac = (r + 0.5) * row_h + pa
    shift = pb + 0.5 * period * (r % 2)
    bc = np.round((b - shift) / period) * period + shift
    return np.hypot(a - ac, b - bc) - radius


def _sd_stripes(c, period, width, phase):
    """Parallel stripes across coordinate ``c`` (SDF, design px)."""
    return np.abs(np.mod(c - phase, period) - period / 2) - width / 2


def _checker(a, b, period, pa, pb, u):
    """Antialiased checkerboard coverage in [0, 1] (u: px per design px)."""
    def half(c, p):
        g = np.abs(np.mod((c - p) / period, 2.0) - 1.0)
        return np.clip((g - 0.5) * period * u + 0.5, 0.0, 1.0)

    sa, sb = half(a, pa), half(b, pb)
    return sa + sb - 2 * sa * sb


# --------------------------------------------------------------------------- looks
def _look(style, seed):
    """Colours and pattern phases of the character ``(style, seed)``: a plain dict."""
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, CHARACTER_STYLES.index(style)])

    def pick(pal):
        return np.asarray(pal[rng.integers(len(pal))], dtype=float)

    shirt = pick(_SHIRT)
    accent = pick(_ACCENT)
    if np.abs(accent - shirt).sum() < 0.5:
        accent = np.array([0.99, 0.97, 0.88])
    look = {"skin": pick(_SKIN), "shirt": shirt, "accent": accent, "pants": pick(_PANTS),
            "shoes": pick(_SHOES), "hair": pick(_HAIR),
            "glove": np.array([0.98, 0.98, 0.96]) if rng.random() < 0.6 else None,
            "long_sleeves": bool(rng.random() < 0.5),
            "period": float(rng.uniform(0.85, 1.15)),
            "phase": {p: rng.uniform(0.0, 40.0, 2) for p in CHARACTER_PARTS},
            "look_dir": float(rng.choice([-1.0, 1.0])),
            "belt": pick([(0.35, 0.22, 0.12), (0.12, 0.12, 0.14), (0.85, 0.65, 0.20)])}
    look["pants_dark"] = look["pants"] * 0.62
    if look["glove"] is None:
        look["glove"] = look["skin"]
    if style == "sketchy":  # pale, paper-like fills
        for key in ("skin", "shirt", "accent", "pants", "shoes", "hair", "glove", "belt"):
            look[key] = 0.55 * look[key] + 0.45
        look["pants_dark"] = look["pants"] * 0.7
    return look


def _blend(col, cover, colour):
    """col (h, w, 3) with ``colour`` painted over it with coverage (h, w)."""
    c = np.clip(cover, 0.0, 1.0)[..., None]
    return col * (1 - c) + np.asarray(colour) * c


def _fabric(style, material, a, b, look, phase, u):
    """Colour (h, w, 3) of ``material`` ("shirt" or "pants") with the style's texture.

    ``a``, ``b`` (h, w) local coords and ``phase`` (2,) in design px; ``u`` px per design px.
    """

    P = look["period"]
    pa, pb = phase
    base = look[material]
    col = np.broadcast_to(base, a.shape + (3,)).copy()
    if material == "shirt":
        if style == "flat":
            cov = _fill(_sd_dots(a, b, 24 * P, 5.5, pa, pb) * u)
        elif style == "shaded":
            cov = _fill(_sd_stripes(0.7 * a + 0.7 * b, 18 * P, 7.0, pa) * u)
        elif style == "patterned":
            cov = _checker(a, b, 13 * P, pa, pb, u)
        else:  # sketchy: sailor stripes across the part
            cov = _fill(_sd_stripes(a, 14 * P, 5.0, pa) * u)
        return _blend(col, cov, look["accent"])
    # trousers
    if style == "flat":
        cov = _fill(_sd_stripes(a, 26 * P, 7.0, pa) * u)
        return _blend(col, cov, look["pants_dark"])
    if style == "shaded":
        cov = _fill(_sd_dots(a, b, 13 * P, 2.6, pa, pb) * u)
        return _blend(col, cov, np.clip(look["pants"] * 1.35 + 0.12, 0, 1))
    if style == "patterned":
        cov = _fill(_sd_stripes(a * 0.6 - b * 0.8, 8 * P, 2.0, pa) * u)
        return _blend(col, 0.85 * cov, look["pants_dark"])
    cov = np.maximum(_fill(_sd_stripes(0.7 * a + 0.7 * b, 7 * P, 1.3, pa) * u),
                     _fill(_sd_stripes(0.7 * a - 0.7 * b, 7 * P, 1.3, pb) * u))
    return _blend(col, 0.7 * cov, look["pants_dark"])


def _part_colour(frame, style, look, a, b, light):
    """Fill colour (h, w, 3) and inner-ink coverage (h, w) of one part, from local coords."""

    u = frame.u
    kind, name = frame.kind, frame.name
    phase = look["phase"][name]
    ink = np.zeros(a.shape)
    lw = 1.9 if style != "sketchy" else 1.4  # inner line width, design px

    def line(sd):  # antialiased inner ink line of width lw centred on sd = 0
        return np.clip(lw * u / 2 + 0.5 - np.abs(sd) * u, 0.0, 1.0)

    if kind == "torso":
        shirt = _fabric(style, "shirt", a, b, look, phase, u)
        pants = _fabric(style, "pants", a, b, look, phase, u)
        top = _fill((_BELT[1] - a) * u)  # 1 above the belt
        col = pants * (1 - top[..., None]) + shirt * top[..., None]
        belt = _fill((np.abs(a - sum(_BELT) / 2) - (_BELT[1] - _BELT[0]) / 2) * u)
        col = _blend(col, belt, look["belt"])
        ink = np.maximum(ink, line(a - _BELT[0]) + line(a - _BELT[1]))
        buckle = np.maximum(np.abs(a - sum(_BELT) / 2) - 7.5, np.abs(b + 4.0) - 8.0)
        col = _blend(col, _fill(buckle * u), (0.93, 0.78, 0.25))
        ink = np.maximum(ink, line(buckle))
        collar = np.hypot(a - 118.0, b) - 15.0  # round neckline showing the neck's skin
        col = _blend(col, _fill(collar * u), look["skin"] * 0.85)
        ink = np.maximum(ink, line(collar) * (a < 119))
        pocket = np.maximum(np.abs(a - 80.0) - 9.0, np.abs(b + 21.0) - 8.0)
        col = _blend(col, _fill(pocket * u), look["shirt"] * 0.8)
        ink = np.maximum(ink, line(pocket))
        button = np.min([np.hypot(a - ac, b - 2.0) for ac in (40.0, 62.0, 84.0)], axis=0) - 2.6
        col = _blend(col, _fill(button * u), look["accent"])
        ink = np.maximum(ink, line(button))
        radius = (40.0, 0.0, 1e3, 46.0)
    elif kind == "neck":
        col = np.broadcast_to(look["skin"], a.shape + (3,)).copy()
        radius = (0.0, 0.0, 1e3, 11.0)
    elif kind == "head":
        ca, cb, ra, rb = _HEAD
        col = np.broadcast_to(look["skin"], a.shape + (3,)).copy()
        hairline = a - (58.0 + 7.0 * np.cos(b / 9.0) - 0.004 * b * b)  # > 0 above it
        tuft = np.minimum(_sd_ellipse(a, b, 83.0, -10.0, 9.0, 12.0),
                          _sd_ellipse(a, b, 84.0, -28.0, 7.0, 9.0))
        hair = np.minimum(np.maximum(-hairline, np.abs(b) - 36.0), tuft)  # SDF, ears excluded
        col = _blend(col, _fill(hair * u), look["hair"])
        ink = np.maximum(ink, line(hair) * (_sd_ellipse(a, b, ca, cb, ra, rb) < -1.0))
        if style in ("flat", "patterned"):  # hair shine streaks
            streak = np.maximum(_sd_stripes(a + 0.5 * b, 9.0, 2.0, phase[0]), hair + 4.0)
            col = _blend(col, 0.5 * _fill(streak * u), np.minimum(look["hair"] * 1.5 + 0.1, 1))
        ear_in = np.minimum(np.abs(_sd_ellipse(a, b, 36.0, 41.0, 6.0, 3.5)),
                            np.abs(_sd_ellipse(a, b, 36.0, -41.0, 6.0, 3.5)))
        ink = np.maximum(ink, 0.8 * line(ear_in))
        d = look["look_dir"]
        for side in (-1.0, 1.0):  # eyes: white, outline, pupil looking sideways, glint
            eb = 15.0 * side
            white = _sd_ellipse(a, b, 42.0, eb, 12.0, 9.0)
            col = _blend(col, _fill(white * u), (1.0, 1.0, 1.0))
            ink = np.maximum(ink, line(white))
            pupil = np.hypot(a - 40.0, b - eb - 3.5 * d) - 5.0
            ink = np.maximum(ink, _fill(pupil * u))
            glint = np.hypot(a - 42.5, b - eb - 3.5 * d + 1.8) - 1.6
            col = _blend(col, _fill(glint * u), (1.0, 1.0, 1.0))
            brow = _sd_segment(a, b, 58.0, eb - 8.0 * side, 61.0 + 2.0 * side, eb + 7.0 * side) - 1.3
            ink = np.maximum(ink, _fill(brow * u))
            blush = _sd_ellipse(a, b, 24.0, 27.0 * side, 5.0, 7.0)
            col = _blend(col, 0.45 * _fill(blush * u), (0.98, 0.50, 0.55))
        nose = _sd_ellipse(a, b, 32.0, 2.5 * d, 5.0, 4.5)
        col = _blend(col, _fill(nose * u), look["skin"] * 0.82)
        ink = np.maximum(ink, 0.8 * line(nose) * (a < 32.5))
        smile = np.hypot(a - 34.0, b - 2.0 * d) - 16.0  # the lower arc of a circle
        ink = np.maximum(ink, line(smile) * np.clip((24.0 - a) * u, 0.0, 1.0))
        tongue = np.maximum(_sd_ellipse(a, b, 18.5, 2.0 * d + 4.0, 2.5, 5.0), a - 20.0)
        col = _blend(col, _fill(tongue * u), (0.90, 0.35, 0.40))
        radius = (ca, cb, ra, rb)
    elif kind in ("upper_arm", "forearm"):
        sleeve = kind == "upper_arm" or look["long_sleeves"]
        if sleeve:
            col = _fabric(style, "shirt", a, b, look, phase, u)
            if kind == "forearm":  # cuff at the wrist
                cuff = np.abs(a - 52.0) - 5.0
                col = _blend(col, _fill(cuff * u), look["accent"])
                ink = np.maximum(ink, line(a - 47.0))
        else:
            col = np.broadcast_to(look["skin"], a.shape + (3,)).copy()
        r0, r1 = _CAPSULES[kind]
        radius = (0.0, 0.0, 1e3, 0.5 * (r0 + r1))
    elif kind in ("thigh", "shin"):
        col = _fabric(style, "pants", a, b, look, phase, u)
        if kind == "shin":  # trouser hem
            ink = np.maximum(ink, line(a - 66.0))
            col = _blend(col, _fill((66.0 - a) * u), look["pants_dark"])
        r0, r1 = _CAPSULES[kind]
        radius = (0.0, 0.0, 1e3, 0.5 * (r0 + r1))
    elif kind == "hand":
        col = np.broadcast_to(look["glove"], a.shape + (3,)).copy()
        for fb in (-2.0, 5.0):  # finger creases
            ink = np.maximum(ink, line(_sd_segment(a, b, 19.0, fb, 28.0, fb + 0.5)))
        ink = np.maximum(ink, 0.8 * line(_sd_segment(a, b, 6.0, -7.0, 12.0, -9.0)))
        radius = (14.0, 1.0, 16.0, 14.0)
    else:  # foot: shoe with a sole, a toe cap and laces
        col = np.broadcast_to(look["shoes"], a.shape + (3,)).copy()
        sole = a - 18.0
        col = _blend(col, _fill(-sole * u), (0.96, 0.95, 0.90))
        ink = np.maximum(ink, line(sole))
        toe = _sd_ellipse(a, b, 12.0, -31.0, 8.0, 9.0)
        col = _blend(col, 0.6 * _fill(np.maximum(toe, sole) * u), (1.0, 1.0, 1.0))
        laces = np.min([np.hypot(a - 5.0, b - bb) for bb in (-8.0, -15.0)], axis=0) - 1.8
        ink = np.maximum(ink, _fill(laces * u))
        radius = (11.0, -9.0, 12.0, 27.0)

    # shading, in the part's frame (so it moves with the part)
    ca, cb, ra, rb = radius
    qa, qb = (a - ca) / ra, (b - cb) / rb
    la, lb = light
    if style == "shaded":
        qq = np.clip(qa * qa + qb * qb, 0.0, 1.0)
        nz = np.sqrt(1.0 - qq)
        s = 1.0 / np.sqrt(la * la + lb * lb + 0.5)
        diffuse = np.clip((qa * la + qb * lb) * s * 0.9 + nz * np.sqrt(0.5) * s, 0.0, 1.0)
        col = col * (0.58 + 0.52 * diffuse)[..., None]
        spec = np.clip((diffuse - 0.86) / 0.14, 0.0, 1.0) ** 2
        col = col + 0.35 * spec[..., None] * (1.0 - col)
        col = col * (1.0 - 0.18 * np.clip((qq - 0.75) / 0.25, 0, 1))[..., None]  # rim
    elif style == "sketchy":
        dark = np.clip(-(qa * la + qb * lb) / np.hypot(la, lb) - 0.15, 0.0, 1.0)
        hatch = _fill(_sd_stripes(0.8 * a - 0.6 * b, 5.0, 1.1, 0.0) * u)
        ink = np.maximum(ink, 0.75 * hatch * np.clip(dark * 3.0, 0.0, 1.0))
    return np.clip(col, 0.0, 1.0), np.clip(ink, 0.0, 1.0)


# --------------------------------------------------------------------------- rendering
def paint_order(skeleton):
    """Back-to-front order of the parts at this pose.

    Without joint depths (``skeleton.depth is None``) this is :data:`PAINT_ORDER`. With
    depths (smaller = nearer the viewer, :class:`~physlab.inbetween.Skeleton`), each part's
    depth is the mean depth of its bone's two joints and parts are painted farthest first,
    :data:`PAINT_ORDER` breaking ties — so an arm given a smaller depth than the torso crosses
    *in front of* it, the occlusions of Brodt & Bessmeltsev's Fig. 2d.

    Returns
    -------
    tuple of part names, back to front.
    """
    if skeleton.depth is None:
        return PAINT_ORDER
    d = skeleton.depth
    part_depth = {}
    for name, (joint, _, _) in _PART_SPECS.items():
        j = CHARACTER_JOINTS.index(joint)
        part_depth[name] = 0.5 * (d[j] + d[_PARENTS[j]])
    return tuple(sorted(PAINT_ORDER, key=lambda n: (-part_depth[n], PAINT_ORDER.index(n))))


def render_character(skeleton, style="shaded", size=512, seed=0):
    """Paint the cartoon character at the pose ``skeleton``.

    Every part is painted from its SDF in its bone's local frame (antialiased: coverage
    ``clip(0.5 - sdf, 0, 1)``), evaluated only inside the part's bounding box, with a fill
    texture and a near-black ink outline just inside its edge; parts are layered in
    :data:`PAINT_ORDER` (see the module docstring), or by joint depth when the skeleton has
    depths (:func:`paint_order`).

    Parameters
    ----------
    skeleton : Skeleton with the topology of :func:`character_skeleton`, joints in pixels
        inside the image; made for this ``size`` (part thickness scales with ``size``, part
        length with the bones).
    style : one of :data:`CHARACTER_STYLES`.
    size : int ≥ 64, output is ``size × size``.
    seed : int, picks colours, sleeves, gloves and pattern phases (never the pose).

    Returns
    -------
    (size, size, 4) uint8 RGBA, alpha 0 on the background.
    """

    size = _check_size(size)
    style = _check_style(style)
    _check_skeleton(skeleton, size)
    look = _look(style, seed)
    light = _rest_light()
    frames = {f.name: f for f in _part_frames(skeleton, size)}
    rgb = np.zeros((size, size, 3))  # premultiplied
    alpha = np.zeros((size, size))
    w = max(1.6, _INK_WIDTH[style] * size / 512)
    ink_col = INK if style != "sketchy" else np.array([0.16, 0.14, 0.22])
    for name in paint_order(skeleton):
        f = frames[name]
        y0, y1, x0, x1 = f.box
        if y1 <= y0 or x1 <= x0:
            continue
        a, b = f.coords()
        sd = f.sdf(a, b)
        cover = _fill(sd)
        if not cover.any():
            continue
        col, ink = _part_colour(f, style, look, a, b, light[name])
        rim = np.clip(sd + w + 0.5, 0.0, 1.0)  # outline: the band -w < sdf < 0
        if style == "sketchy":  # a second, wobbly pencil line just inside the outline
            wob = sd + w + 1.6 * f.u + 0.9 * f.u * np.sin(a * 0.21 + b * 0.13 + look["phase"][name][0])
            rim = np.maximum(rim, 0.55 * np.clip(0.7 * f.u + 0.5 - np.abs(wob), 0.0, 1.0))
        ink = np.maximum(ink, rim)
        col = _blend(col, ink, ink_col)
        c = cover[..., None]
        rgb[y0:y1, x0:x1] = col * c + rgb[y0:y1, x0:x1] * (1 - c)
        alpha[y0:y1, x0:x1] = cover + alpha[y0:y1, x0:x1] * (1 - cover)
    a = alpha[..., None]
    out = np.concatenate([np.where(a > 0, rgb / np.maximum(a, 1e-12), 0.0), a], axis=-1)
    return np.round(np.clip(out, 0.0, 1.0) * 255).astype(np.uint8)


def character_part_labels(skeleton, size=512):
    """Which part is visible at each pixel (the layering of :func:`render_character`).

    Returns
    -------
    (size, size) int8: index into :data:`CHARACTER_PARTS` of the front-most part whose
    silhouette contains the pixel centre, -1 on the background.
    """
    size = _check_size(size)
    _check_skeleton(skeleton, size)
    labels = np.full((size, size), -1, dtype=np.int8)
    frames = {f.name: f for f in _part_frames(skeleton, size)}
    for name in paint_order(skeleton):
        f = frames[name]
        y0, y1, x0, x1 = f.box
        if y1 <= y0 or x1 <= x0:
            continue
        inside = f.sdf(*f.coords()) < 0
        labels[y0:y1, x0:x1][inside] = CHARACTER_PARTS.index(name)
    return labels


def part_overlaps(skeleton, size=512, margin=1.0):
    """Pairs of non-adjacent parts that touch or overlap (occlusions) at this pose.

    Two parts *touch* where a pixel lies within ``margin`` px of both silhouettes
    (``max(sdf_i, sdf_j) < margin``), i.e. where they are less than about ``2 margin`` px
    apart. Pairs in :data:`ADJACENT_PARTS` (sharing a joint) are allowed to overlap and are
    not reported.

    Parameters
    ----------
    skeleton : Skeleton of the character's topology inside the ``size × size`` image.
    size : int ≥ 64.
    margin : px ≥ 0.

    Returns
    -------
    list of (part_i, part_j, n_pixels), part names in :data:`CHARACTER_PARTS` order; empty
    when the pose is occlusion-free.
    """
    size = _check_size(size)
    _check_skeleton(skeleton, size)
    frames = _part_frames(skeleton, size)
    sdfs = [f.sdf(*f.coords()) if f.box[1] > f.box[0] and f.box[3] > f.box[2] else None
            for f in frames]
    out = []
    for i, fi in enumerate(frames):
        for j in range(i + 1, len(frames)):
            fj = frames[j]
            if frozenset((fi.name, fj.name)) in ADJACENT_PARTS or sdfs[i] is None \
                    or sdfs[j] is None:
                continue
            y0, x0 = max(fi.box[0], fj.box[0]), max(fi.box[2], fj.box[2])
            y1, x1 = min(fi.box[1], fj.box[1]), min(fi.box[3], fj.box[3])
            if y1 <= y0 or x1 <= x0:
                continue
            di = sdfs[i][y0 - fi.box[0]:y1 - fi.box[0], x0 - fi.box[2]:x1 - fi.box[2]]
            dj = sdfs[j][y0 - fj.box[0]:y1 - fj.box[0], x0 - fj.box[2]:x1 - fj.box[2]]
            n = int(np.count_nonzero(np.maximum(di, dj) < margin))
            if n:
                out.append((fi.name, fj.name, n))
    return out


def _full_sdf(frame, size):
    """A part's SDF over the whole image (+inf outside its box)."""
    out = np.full((size, size), np.inf)
    y0, y1, x0, x1 = frame.box
    if y1 > y0 and x1 > x0:
        out[y0:y1, x0:x1] = frame.sdf(*frame.coords())
    return out


def character_occlusions(skeleton, size=512, min_area=30, min_run=3):
    """The true occlusion regions and T-junctions of the character at this pose.

    A pixel is *occluded* where a part lies over another part that does not share a joint
    with it (:func:`paint_order`, :data:`ADJACENT_PARTS`). Each connected component of
    occluded pixels (at least ``min_area`` px) is one
    :class:`~physlab.inbetween.occlusion.Occlusion`: its *front* parts are those visible in it,
    its *back* parts the others covering it. Its T-junctions are the points where the region's
    outline switches from following the front parts' silhouette to the back parts' — where, in
    the drawing, a back part's ink line ends against the occluder's (Brodt & Bessmeltsev
    Fig. 7); runs shorter than ``min_run`` outline points are ignored. This is the ground
    truth a user would annotate (Sec. 4); tests and the occlusion benchmark use it.

    Returns
    -------
    list of Occlusion (``mask`` (size, size) bool, ``t_junctions`` (m, 2) px) with ``label``
    ``"front+parts/back+parts"``.
    """
    from scipy import ndimage

    size = _check_size(size)
    order, sdf, inside = _part_fields(skeleton, size)
    occluded = np.zeros((size, size), bool)
    for i, back in enumerate(order):
        for front in order[i + 1:]:
            if frozenset((front, back)) not in ADJACENT_PARTS:
                occluded |= inside[back] & inside[front]
    visible = np.full((size, size), -1)
    for i, n in enumerate(order):
        visible[inside[n]] = i
    labels, k = ndimage.label(occluded)
    out = []
    for c in range(1, k + 1):
        comp = labels == c
        if comp.sum() < min_area:
            continue
        front = sorted({order[i] for i in np.unique(visible[comp])})
        back = sorted(n for n in order if n not in front and np.any(inside[n] & comp))
        if not back:
            continue
        out.append(_region_occlusion(comp, front, back, sdf, size, min_run))
    return out


def _part_fields(skeleton, size):
    """``(order, sdf, inside)``: the parts in paint order (:func:`paint_order`), each part's
    signed distance field and inside mask at ``size``."""
    _check_skeleton(skeleton, size)
    frames = {f.name: f for f in _part_frames(skeleton, size)}
    order = paint_order(skeleton)
    sdf = {n: _full_sdf(frames[n], size) for n in order}
    return order, sdf, {n: sdf[n] < 0 for n in order}


def _region_occlusion(comp, front, back, sdf, size, min_run):
    """The :class:`~physlab.inbetween.occlusion.Occlusion` of the occluded pixels ``comp``
    where the parts ``front`` cover ``back``: its T-junctions are where the outline switches
    from the front parts' silhouette to the back parts' (by the parts' signed distances
    ``sdf``)."""
    from skimage.measure import find_contours

    from .occlusion import Occlusion, switch_points

    sd_front = np.min([sdf[n] for n in front], axis=0)
    sd_back = np.min([sdf[n] for n in back], axis=0)
    contour = max(find_contours(np.pad(comp, 1).astype(float), 0.5), key=len)
    yx = contour[:-1] - 1.0
    ij = np.clip(np.round(yx).astype(int), 0, size - 1)
    on_front = np.abs(sd_front[ij[:, 0], ij[:, 1]]) < np.abs(sd_back[ij[:, 0], ij[:, 1]])
    return Occlusion(comp, switch_points(yx[:, ::-1], on_front, min_run),
                     label=f"{'+'.join(front)}/{'+'.join(back)}")


def character_layered_occlusions(skeleton, size=512, min_area=30, min_run=3):
    """The true occlusion regions of the character as *one mask per hidden layer*, sorted by
    depth: the annotation Brodt & Bessmeltsev ask for where more than two parts overlap
    (Sec. 4: "occlusion masks, one per layer, sorted by depth", Fig. 9).

    A part is *hidden* at a pixel where a part painted over it (:func:`paint_order`) that does
    not share a joint with it (:data:`ADJACENT_PARTS`) covers it. Parts are grouped by depth
    (the mean depth of their bone's joints, as :func:`paint_order`); for every depth level,
    nearest first, each connected component (at least ``min_area`` px) of the pixels where a
    part of that level is hidden is one :class:`~physlab.inbetween.occlusion.Occlusion` — its
    *back* parts are the hidden ones of that level, its *front* parts those covering them. Its
    T-junctions are where its outline switches from the front parts' silhouette to the back
    parts' (as :func:`character_occlusions`). Where three parts overlap (a forearm in front of
    the torso in front of the other arm), the masks of two levels overlap, and
    :func:`~physlab.inbetween.occlusion.build_layered_template` gives the overlap a third
    layer; where only two parts overlap the regions are those of :func:`character_occlusions`
    up to how the union of occluded pixels is split.

    Returns
    -------
    list of Occlusion, the hidden parts' depth non-decreasing (nearest hidden layer first);
    ``label`` ``"front+parts/back+parts"``.
    """
    from scipy import ndimage

    size = _check_size(size)
    order, sdf, inside = _part_fields(skeleton, size)
    d = np.zeros(len(CHARACTER_JOINTS)) if skeleton.depth is None else skeleton.depth
    part_depth = {}
    for name, (joint, _, _) in _PART_SPECS.items():
        j = CHARACTER_JOINTS.index(joint)
        part_depth[name] = round(float(0.5 * (d[j] + d[_PARENTS[j]])), 9)
    hidden, covers = {}, {}   # part -> pixels where it is hidden; part -> parts covering it
    for i, back in enumerate(order):
        front = [f for f in order[i + 1:] if frozenset((f, back)) not in ADJACENT_PARTS
                 and np.any(inside[f] & inside[back])]
        if front:
            hidden[back] = inside[back] & np.any([inside[f] for f in front], axis=0)
            covers[back] = front
    out = []
    for level in sorted({part_depth[p] for p in hidden}):
        backs = [p for p in hidden if part_depth[p] == level]
        occ = np.any([hidden[p] for p in backs], axis=0)
        labels, k = ndimage.label(occ)
        for c in range(1, k + 1):
            comp = labels == c
            if comp.sum() < min_area:
                continue
            back = sorted(p for p in backs if np.any(hidden[p] & comp))
            front = sorted({f for p in back for f in covers[p] if np.any(inside[f] & comp)})
            out.append(_region_occlusion(comp, front, back, sdf, size, min_run))
    return out


# --------------------------------------------------------------------------- benchmark
@dataclass(frozen=True, eq=False)
class InbetweenPair:
    """Two keyframes of the character and the skeletal motion between them.

    Attributes
    ----------
    name : str.
    kind : "tight" (every bone's local angle changes by ≤ 25°), "far" (some bone's by > 90°)
        or "occluded" (limbs cross the body: :func:`occlusion_benchmark`).
    style : one of :data:`CHARACTER_STYLES`.
    seed : int, the character's colours and pattern phases.
    skeleton0, skeleton1 : Skeleton, the key poses (topology of :func:`character_skeleton`).
    size : int, images are ``size × size``.
    mask_per_layer : bool, how :meth:`occlusions` annotates: False — one region per connected
        occluded area (:func:`character_occlusions`); True — one mask per hidden layer, sorted
        by depth, overlapping where three parts overlap (:func:`character_layered_occlusions`,
        Sec. 4).
    """

    name: str
    kind: str
    style: str
    seed: int
    skeleton0: Skeleton
    skeleton1: Skeleton
    size: int = 512
    mask_per_layer: bool = False

    def __post_init__(self):
        if self.kind not in ("tight", "far", "occluded"):
            raise ValueError(f"kind must be 'tight', 'far' or 'occluded', got {self.kind!r}")
        _check_style(self.style)
        size = _check_size(self.size)
        _check_skeleton(self.skeleton0, size, "skeleton0")
        _check_skeleton(self.skeleton1, size, "skeleton1")

    def __repr__(self):
        return (f"InbetweenPair({self.name!r}, kind={self.kind!r}, style={self.style!r}, "
                f"seed={self.seed}, size={self.size})")

    def keyframes(self):
        """The two key drawings: ``(img0, img1)``, each (size, size, 4) uint8 RGBA."""
        return (render_character(self.skeleton0, self.style, self.size, self.seed),
                render_character(self.skeleton1, self.style, self.size, self.seed))

    def skeleton_at(self, t):
        """The skeleton at time ``t`` ∈ [0, 1] (a list for an array ``t``): the local-angle
        blend of the keys (``interpolate(..., method="local_angles")``), by definition."""
        ts = np.asarray(t, dtype=float)
        if np.any((ts < 0) | (ts > 1)) or not np.all(np.isfinite(ts)):
            raise ValueError(f"t must lie in [0, 1], got {t}")
        return _skeleton.interpolate(self.skeleton0, self.skeleton1, t, method="local_angles")

    def ground_truth(self, t):
        """The true inbetween(s): the character rendered at :meth:`skeleton_at` ``(t)``.

        Parameters
        ----------
        t : float in [0, 1] or (m,) floats.

        Returns
        -------
        (size, size, 4) uint8 for a scalar ``t``, else (m, size, size, 4).
        """
        sk = self.skeleton_at(t)
        if isinstance(sk, _skeleton.Skeleton):
            return render_character(sk, self.style, self.size, self.seed)
        return np.stack([render_character(s, self.style, self.size, self.seed) for s in sk])

    def animation(self, n_frames):
        """The skeletal motion ``x_i(t)``: ``n_frames`` Skeletons at ``t = linspace(0, 1, n)``."""
        if isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) \
                or n_frames < 2:
            raise ValueError(f"n_frames must be an int >= 2, got {n_frames!r}")
        return _skeleton.interpolate(self.skeleton0, self.skeleton1,
                                     np.linspace(0.0, 1.0, int(n_frames)), method="local_angles")

    def occlusions(self):
        """The true occlusions of both keys: ``(list, list)`` of
        :class:`~physlab.inbetween.occlusion.Occlusion` (:func:`character_occlusions`, or
        :func:`character_layered_occlusions` with ``mask_per_layer``)."""
        find = character_layered_occlusions if self.mask_per_layer else character_occlusions
        return find(self.skeleton0, self.size), find(self.skeleton1, self.size)

    def angle_changes(self):
        """(J,) degrees, |shortest-arc change| of each bone's local angle (0 for the root)."""
        d = _skeleton._wrap(self.skeleton1.local_angles() - self.skeleton0.local_angles())
        return np.abs(np.rad2deg(d))


#: The benchmark: (name, kind, style, seed, pose0 kwargs, pose1 kwargs) of pose_character
#: applied to the rest skeleton; offsets in design px (scaled with the image size).
_BENCHMARK = [
    # ---- tight: every bone's local angle changes by <= 25°
    ("nod", "tight", "flat", 0, {}, {"head": -18, "neck": -6, "torso": 4}),
    ("wave_small", "tight", "shaded", 1,
     {"left_upper_arm": -20, "left_forearm": -20},
     {"left_upper_arm": -35, "left_forearm": -42}),
    ("lean", "tight", "patterned", 2,
     {"torso": -4},
     {"torso": 10, "head": -12, "left_upper_arm": -14, "right_upper_arm": -10,
      "offset": (-6, 0)}),
    ("step", "tight", "sketchy", 3,
     {"left_thigh": -4, "right_thigh": 4},
     {"left_thigh": -18, "left_shin": 20, "right_thigh": 10, "torso": 5, "offset": (10, -4)}),
    ("shrug", "tight", "shaded", 4,
     {},
     {"left_clavicle": -10, "right_clavicle": 10, "left_upper_arm": 14, "right_upper_arm": -14,
      "left_forearm": -22, "right_forearm": 22, "head": 8}),
    ("bounce", "tight", "flat", 5,
     {"offset": (0, -8)},
     {"offset": (0, 10), "left_thigh": -16, "left_shin": 20, "right_thigh": 16,
      "right_shin": -20, "left_upper_arm": -20, "right_upper_arm": 20,
      "stretch": {"torso": 0.92, "head": 0.94}}),
    # ---- far: some limb's local angle changes by > 90°
    ("arm_swing", "far", "flat", 6,
     {"left_upper_arm": -75, "left_forearm": 50},
     {"left_upper_arm": 40, "left_forearm": -30}),
    ("wave_hello", "far", "patterned", 7,
     {"right_upper_arm": -5},
     {"right_upper_arm": 25, "right_forearm": 115, "head": 10}),
    ("side_kick", "far", "shaded", 8,
     {"left_thigh": -5, "left_shin": -100},
     {"left_thigh": -62, "left_shin": -5, "torso": 12, "right_upper_arm": -20,
      "offset": (-12, 0)}),
    ("jumping_jack", "far", "sketchy", 9,
     {"left_upper_arm": 45, "right_upper_arm": -45, "left_thigh": 8, "right_thigh": -8},
     {"left_upper_arm": -90, "right_upper_arm": 90, "left_forearm": -20, "right_forearm": 20,
      "left_thigh": -14, "right_thigh": 14, "offset": (0, -12)}),
    ("punch", "far", "flat", 10,
     {"right_upper_arm": 55, "right_forearm": -125, "left_upper_arm": 20},
     {"right_upper_arm": -5, "right_forearm": -5, "torso": -6, "left_upper_arm": 30,
      "left_forearm": 30}),
    ("high_knee", "far", "patterned", 11,
     {},
     {"right_thigh": 80, "right_shin": -95, "left_upper_arm": -40, "right_upper_arm": 30,
      "offset": (6, -10)}),
    ("tumble", "far", "shaded", 12,
     {},
     {"rotation": 95, "left_upper_arm": -30, "right_upper_arm": 30, "offset": (0, -20)}),
    ("disco", "far", "sketchy", 13,
     {"left_upper_arm": 35, "left_forearm": 20, "right_upper_arm": -20},
     {"left_upper_arm": -95, "left_forearm": -15, "right_upper_arm": 40, "right_forearm": 35,
      "head": -15, "torso": -8}),
]


def inbetween_benchmark(size=512):
    """Inbetweening test pairs of the cartoon character: 6 tight and 8 far, mixed styles.

    Every pair is occlusion-free at every ``t`` in [0, 1] (only parts sharing a joint
    touch, :func:`part_overlaps`) and stays inside the image. Largest local-angle changes:

    ============ ===== ======================================================================
    name         kind  motion
    ============ ===== ======================================================================
    nod          tight head 18°, neck 6°, torso 4°
    wave_small   tight left upper arm 15°, forearm 22°
    lean         tight torso 14°, head 12°, arms 10–14°, small shift
    step         tight left thigh 14°, shin 20°, right thigh 6°, torso 5°
    shrug        tight clavicles 10°, upper arms 14°, forearms 22°, head 8°
    bounce       tight knees out 16°/20°, arms 20°, torso and head squashed 8 %/6 %
    arm_swing    far   left upper arm 115° (raised → lowered), elbow 80°
    wave_hello   far   right forearm 115° (straight → raised), upper arm 30°
    side_kick    far   left shin 95° (folded → straight), thigh 57°, torso 12°
    jumping_jack far   both upper arms 135° (down → up), legs 22°, hop
    punch        far   right forearm 120° (folded → straight), upper arm 60°
    high_knee    far   right thigh 80° (raised sideways), shin 95° (hangs down)
    tumble       far   whole body 95° about the pelvis, arms 30°
    disco        far   left upper arm 130° (down → up), right arm 60°/35°, head 15°
    ============ ===== ======================================================================

    Parameters
    ----------
    size : int ≥ 64, image size of the pairs.

    Returns
    -------
    list of :class:`InbetweenPair` (names in the order tight …, far …).
    """
    size = _check_size(size)
    rest = character_skeleton(size)
    u = _unit(size)

    def pose(kw):
        kw = dict(kw)
        if "offset" in kw:
            kw["offset"] = np.asarray(kw["offset"], dtype=float) * u
        return pose_character(rest, **kw)

    return [InbetweenPair(name, kind, style, seed, pose(k0), pose(k1), size)
            for name, kind, style, seed, k0, k1 in _BENCHMARK]


#: Occluding pairs: (name, style, seed, pose0, pose1, joint depths (others 0; smaller = nearer)).
_OCCLUSION_BENCHMARK = [
    ("fold_arm", "flat", 20, {"left_upper_arm": 35, "left_forearm": -12},
     {"left_upper_arm": 60, "left_forearm": 120}, {"left_elbow": -1.0, "left_hand": -1.0}),
    ("arm_behind", "shaded", 21, {"right_upper_arm": -35, "right_forearm": 12},
     {"right_upper_arm": -60, "right_forearm": -125}, {"right_elbow": 1.0, "right_hand": 1.0}),
    ("cross_legs", "patterned", 22, {"left_thigh": -5},
     {"left_thigh": 40, "left_shin": -8}, {"left_knee": -1.0, "left_foot": -1.0}),
    ("cross_step", "patterned", 23, {"left_thigh": 28, "left_shin": 20},
     {"left_thigh": 45, "left_shin": -45, "right_thigh": -8},
     {"left_knee": -1.0, "left_foot": -1.0}),
]


def occlusion_benchmark(size=512):
    """Pairs whose limbs cross the body (Brodt & Bessmeltsev's title case, Fig. 2d).

    ============ =================================================================
    name         motion
    ============ =================================================================
    fold_arm     left forearm swings from hanging to folded across the belly, in front
    arm_behind   right forearm swings from hanging to folded behind the back
    cross_legs   left leg crosses in front of the right one (key 0: legs apart)
    cross_step   left leg in front of the right at both keys: crossed at the feet, then
                 at the knees
    ============ =================================================================

    In ``cross_legs`` key 0's legs are apart (a hole between them), so its single-sheet
    template is already correctly layered and the two templates can only differ at key 1;
    ``cross_step`` occludes at both keys, the paper's title case.

    The skeletons carry joint depths (the moving limb nearer or farther than the body), the
    renderer paints in depth order (:func:`paint_order`), and :meth:`InbetweenPair.occlusions`
    gives each key's true occlusion regions and T-junctions.

    Returns
    -------
    list of :class:`InbetweenPair` of kind "occluded".
    """
    return _occluded_pairs(_OCCLUSION_BENCHMARK, size)


def _occluded_pairs(table, size, **kw):
    """The "occluded" :class:`InbetweenPair` of each ``(name, style, seed, pose0, pose1,
    joint depths)`` row of ``table`` (other joints at depth 0); ``kw`` to each pair."""
    size = _check_size(size)
    rest = character_skeleton(size)
    out = []
    for name, style, seed, k0, k1, depth in table:
        d = {j: 0.0 for j in CHARACTER_JOINTS}
        d.update(depth)
        out.append(InbetweenPair(name, "occluded", style, seed,
                                 pose_character(rest, **k0).with_depth(d),
                                 pose_character(rest, **k1).with_depth(d), size, **kw))
    return out


#: Three overlapping layers: (name, style, seed, pose0, pose1, joint depths (others 0)).
_THREE_LAYER_BENCHMARK = [
    ("arms_around", "flat", 24,
     {"left_upper_arm": 35, "left_forearm": -12, "right_upper_arm": -35, "right_forearm": 12},
     {"left_upper_arm": 45, "left_forearm": 105, "right_upper_arm": -45, "right_forearm": -110},
     {"left_elbow": -1.0, "left_hand": -1.0, "right_elbow": 1.0, "right_hand": 1.0}),
]


def occlusion_benchmark_three_layers(size=512):
    """A pair where three parts overlap at key 1 (Brodt & Bessmeltsev Fig. 9: the boy's right
    arm behind the body that is behind his left arm).

    ============ =================================================================
    name         motion
    ============ =================================================================
    arms_around  both arms from hanging to folded: the left forearm across the belly in
                 front, the right forearm behind the back; they cross behind/over the
                 belly, so left forearm, torso and right forearm overlap there
    ============ =================================================================

    Its occlusions are one mask per hidden layer sorted by depth
    (:func:`character_layered_occlusions`, ``mask_per_layer=True``): at key 1 the torso hidden
    by the left forearm, then the right forearm hidden by the torso and the left forearm —
    the two masks overlap where the forearms cross, and the layered template gives that
    overlap a third layer. Kept apart from :func:`occlusion_benchmark` so the four pairs
    there (and the numbers quoted for them) stay as they are.

    Returns
    -------
    list of :class:`InbetweenPair` of kind "occluded".
    """
    return _occluded_pairs(_THREE_LAYER_BENCHMARK, size, mask_per_layer=True)
