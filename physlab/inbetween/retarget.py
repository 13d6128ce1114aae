"""Pose a drawn character's 2D skeleton with a 3D BVH motion (AnimatedDrawings-style retargeting).

A drawing's skeleton (:class:`~physlab.inbetween.skeleton.Skeleton`, pixels, y down) is posed
frame by frame from a BVH clip (:class:`~physlab.motion.bvh.BVHMotion`) the way
AnimatedDrawings does it [Smith et al. 2023, "A Method for Animating Children's Drawings of
the Human Figure", ACM TOG 42(3), Sec. 5; facebookresearch/AnimatedDrawings
``animated_drawings/model/retargeter.py``]:

1. **Projection.** The BVH world joints ``P`` ``(T, J_bvh, 3)`` are projected orthographically
   onto a camera plane, Eq. (1): ``(x, y) = (P · e_x, -P · u)`` with ``u`` the BVH's up axis
   (y or z, inferred) so that BVH up becomes pixel y down. ``view="front"`` puts the camera in
   front of the actor: ``e_x`` = the actor's left, so a person facing the viewer shows their
   left hand on the image's right, like the drawings' ``left_*`` joints. The actor's facing
   (from its left->right shoulder and hip vectors) is taken in every frame
   (``follow_turns=True``, the default, as AnimatedDrawings) or only at ``reference_frame``.
   ``view="side"`` looks at the actor's left side (it faces screen right, AnimatedDrawings'
   "sagittal" plane); ``view="auto"`` picks front or side for the arms and for the legs by
   PCA, like AnimatedDrawings' ``pca`` projection groups.
2. **Bone directions.** The mapping pairs a drawing joint ``j`` with two BVH joints
   ``(a, b)``; the bone into ``j`` (``parents[j] -> j``) takes the screen angle ``phi`` of the
   projected segment ``a -> b`` and keeps the drawing's bone length ``L_j``:

   * ``method="absolute"`` (default, as AnimatedDrawings): ``theta_j(t) = phi(t)``;
   * ``method="relative"``: ``theta_j(t) = theta_j^rest + wrap(phi(t) - phi(t_ref))``, the
     BVH bone's rotation since ``reference_frame`` applied to the drawing's rest direction,
     so the reference frame gives back the drawing's rest skeleton.

   Absolute is the default because the BVH's reference pose (a T-pose in the fair1 clips,
   arms hanging in jumping_jacks) and the drawing's rest pose (arms out in char1–3, raised in
   char4) differ by up to ~90° per limb, and with relative directions that offset stays in
   every frame: driven by jumping_jacks (arms hanging at frame 0), char1 (arms drawn out)
   lifts its arms above its head when the actor lifts them to shoulder height and bends a
   forearm across its head at the top, and its legs stay splayed as drawn while the actor's
   are together.
   Absolute directions give every character the actor's pose, as in AnimatedDrawings' demos.
3. **Unmapped bones** (shoulders, pelvis->hip bones, the zero-length root->hip bone) keep
   their rest angle *relative to the parent bone*; bones whose parent is the root keep their
   rest absolute angle (AnimatedDrawings never rotates the root). A mapped segment that
   projects to (almost) a point, ``|proj| <= MIN_PROJECTED_FRACTION * |3D|``, has no
   direction and is treated as unmapped in that frame.
4. **Forward kinematics** from the root: ``x_j = x_p + L_j (cos theta_j, sin theta_j)``, so
   every bone keeps its drawn length exactly (to rounding).
5. **Root.** With ``root_motion=True`` the root moves by the projected BVH root displacement
   since ``reference_frame`` times ``s = (drawing leg length) / (BVH leg length)`` (px per BVH
   unit: summed lengths of the mapped knee/foot bones, AnimatedDrawings'
   ``char_bvh_root_offset``); with ``follow_turns`` the horizontal part accumulates each
   frame's step in that frame's view. With ``root_motion=False`` the root stays at the
   drawing's root. Nothing is clipped; on the six example clips the posed joints stay within
   half the drawing's size of its image.

Joint maps (:func:`default_mapping`, from AnimatedDrawings' ``config/retarget/*.yaml``; the
drawing joint names are those of the example characters ``char1``–``char6``) give, for each
drawing joint, the BVH segment that orients the bone into it:

=============  =================  ===================  ===================
drawing joint  fair1 (fair1_ppf)  cmu1 (cmu1_pfp)      rokoko (mixamo_fff)
=============  =================  ===================  ===================
torso          Hips -> Spine3     Hips -> Chest2       Hips -> Spine2
neck           Hips -> Neck       Hips -> Head         Hips -> Head
X_elbow        XArm -> XForeArm   XShoulder -> XElbow  XArm -> XForeArm
X_hand         XForeArm -> XHand  XElbow -> XWrist     XForeArm -> XHand
X_knee         XUpLeg -> XLeg     XHip -> XKnee        XUpLeg -> XLeg
X_foot         XLeg -> XFoot      XKnee -> XAnkle      XLeg -> XFoot
=============  =================  ===================  ===================

with ``X_`` = ``left_`` / ``right_`` in the drawing and ``X`` = ``Left`` / ``Right`` in the BVH.

Extra limbs (char5's ``*_elbow1..3``/``*_hand1..3``, char6's ``*_knee_f/_b``, ``*_foot_f/_b``)
follow the same BVH limb as in ``six_arms.yaml`` / ``four_legs.yaml``; a torso drawn lying
(char6, ``|dx| > |dy|``) is not mapped, as in ``four_legs.yaml``; the neck is dropped when it
is drawn below the shoulder line (AnimatedDrawings' ``char_runtime_checks``).

Attribution: the BVH clips, characters and joint maps are from AnimatedDrawings (MIT,
© Meta Platforms, Inc. and affiliates); ``cmu1/jumping_jacks.bvh`` derives from the CMU
Graphics Lab Motion Capture Database (mocap.cs.cmu.edu, NSF EIA-0196217).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from physlab.motion.bvh import BVHMotion, read_bvh

from .skeleton import Skeleton, _wrap

__all__ = [
    "ANIMATED_DRAWINGS_MOTIONS",
    "ANIMATED_DRAWINGS_START_FRAMES",
    "CMU1_MAPPING",
    "FAIR1_MAPPING",
    "MIN_PROJECTED_FRACTION",
    "ROKOKO_MAPPING",
    "KeyframePoses",
    "bvh_joint_depths",
    "bvh_to_skeletons",
    "default_mapping",
    "keyframe_poses",
    "load_character",
    "load_motion",
]

#: AnimatedDrawings example motions: name -> path relative to
#: ``<external data>/animated_drawings/examples/bvh/``.
ANIMATED_DRAWINGS_MOTIONS = {
    "jumping_jacks": "cmu1/jumping_jacks.bvh",
    "dab": "fair1/dab.bvh",
    "jumping": "fair1/jumping.bvh",
    "wave_hello": "fair1/wave_hello.bvh",
    "zombie": "fair1/zombie.bvh",
    "jesse_dance": "rokoko/jesse_dance.bvh",
}

#: First frame AnimatedDrawings plays (``start_frame_idx`` of ``config/motion/<name>.yaml``);
#: ``jumping.bvh`` starts with 150 frames of standing still.
ANIMATED_DRAWINGS_START_FRAMES = {name: 0 for name in ANIMATED_DRAWINGS_MOTIONS} | {
    "jumping": 150}

#: Drawing joint (base name) -> (proximal, distal) BVH joint, ``fair1_ppf.yaml``.
FAIR1_MAPPING = {
    "torso": ("Hips", "Spine3"), "neck": ("Hips", "Neck"),
    "left_elbow": ("LeftArm", "LeftForeArm"), "left_hand": ("LeftForeArm", "LeftHand"),
    "right_elbow": ("RightArm", "RightForeArm"), "right_hand": ("RightForeArm", "RightHand"),
    "left_knee": ("LeftUpLeg", "LeftLeg"), "left_foot": ("LeftLeg", "LeftFoot"),
    "right_knee": ("RightUpLeg", "RightLeg"), "right_foot": ("RightLeg", "RightFoot"),
}
#: ``cmu1_pfp.yaml`` (CMU, 3dsMax-friendly naming).
CMU1_MAPPING = {
    "torso": ("Hips", "Chest2"), "neck": ("Hips", "Head"),
    "left_elbow": ("LeftShoulder", "LeftElbow"), "left_hand": ("LeftElbow", "LeftWrist"),
    "right_elbow": ("RightShoulder", "RightElbow"), "right_hand": ("RightElbow", "RightWrist"),
    "left_knee": ("LeftHip", "LeftKnee"), "left_foot": ("LeftKnee", "LeftAnkle"),
    "right_knee": ("RightHip", "RightKnee"), "right_foot": ("RightKnee", "RightAnkle"),
}
#: ``mixamo_fff.yaml`` (Rokoko / Mixamo naming: no Spine3).
ROKOKO_MAPPING = dict(FAIR1_MAPPING, torso=("Hips", "Spine2"), neck=("Hips", "Head"))

#: Projected segments shorter than this fraction of their 3D length have no direction.
MIN_PROJECTED_FRACTION = 1e-6

# Suffixes of extra limbs: char5 "left_elbow2", char6 "left_knee_f".
_LIMB_SUFFIX = re.compile(r"(\d+|_[fb])$")
_VIEWS = ("front", "side")
_METHODS = ("absolute", "relative")
_AXES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0),
         "+z": (0, 0, 1), "-z": (0, 0, -1)}


def _base_name(name):
    """Drawing joint name without the extra-limb suffix: ``left_elbow2`` -> ``left_elbow``."""
    return _LIMB_SUFFIX.sub("", name)


def _examples_dir():
    from physlab.datasets import external_data_dir

    root = external_data_dir()
    if root is None:
        raise FileNotFoundError(
            "the external data folder was not found: set PHYSLAB_EXTERNAL_DATA to the folder "
            "that holds animated_drawings/ (or place it at <repo root>/../shared/data)")
    return root / "animated_drawings" / "examples"


def load_motion(motion):
    """A :class:`BVHMotion` from itself, a BVH path, or a name of
    :data:`ANIMATED_DRAWINGS_MOTIONS` (read from the external data folder)."""
    if isinstance(motion, BVHMotion):
        return motion
    if isinstance(motion, str) and motion in ANIMATED_DRAWINGS_MOTIONS:
        return read_bvh(_examples_dir() / "bvh" / ANIMATED_DRAWINGS_MOTIONS[motion])
    if isinstance(motion, (str, Path)):
        path = Path(motion)
        if not path.is_file():
            raise FileNotFoundError(f"no BVH file at {path} (and not one of the names "
                                    f"{sorted(ANIMATED_DRAWINGS_MOTIONS)})")
        return read_bvh(path)
    raise TypeError(f"motion must be a BVHMotion, a path or one of "
                    f"{sorted(ANIMATED_DRAWINGS_MOTIONS)}, got {type(motion).__name__}")


def load_character(character):
    """A :class:`Skeleton` from itself, a ``char_cfg.yaml`` path, or an AnimatedDrawings
    example name ``"char1"`` … ``"char6"`` (read from the external data folder)."""
    from physlab.datasets import ANIMATED_DRAWINGS

    if isinstance(character, Skeleton):
        return character
    if isinstance(character, str) and character in ANIMATED_DRAWINGS:
        return Skeleton.from_animated_drawings(
            _examples_dir() / "characters" / character / "char_cfg.yaml")
    if isinstance(character, (str, Path)):
        return Skeleton.from_animated_drawings(character)
    raise TypeError(f"character must be a Skeleton, a char_cfg.yaml path or one of "
                    f"{ANIMATED_DRAWINGS}, got {type(character).__name__}")


def _bvh_table(names):
    """The AnimatedDrawings joint map whose BVH joints a skeleton has (fair1 first: the
    rokoko map is fair1's without Spine3), or None."""
    names = set(names)
    for mapping in (FAIR1_MAPPING, CMU1_MAPPING, ROKOKO_MAPPING):
        if all(a in names and b in names for a, b in mapping.values()):
            return mapping
    return None


def default_mapping(bvh_motion, skeleton):
    """The AnimatedDrawings joint map of a BVH skeleton, restricted to a drawing's joints.

    The BVH naming picks the map (:data:`FAIR1_MAPPING` when it has ``Spine3``/``UpLeg``
    joints, :data:`CMU1_MAPPING` for ``Chest2``/``Hip``/``Ankle``, :data:`ROKOKO_MAPPING` for
    Mixamo names without ``Spine3``); drawing joints are matched on their base name, so extra
    limbs (``left_hand2``, ``right_knee_b``) follow the same BVH limb. The torso is left out
    when drawn closer to horizontal than vertical (a four-legged body), and the neck when
    drawn below the shoulder line (AnimatedDrawings' ``char_runtime_checks``).

    Parameters
    ----------
    bvh_motion : BVHMotion, BVH path or name in :data:`ANIMATED_DRAWINGS_MOTIONS`.
    skeleton : Skeleton, char_cfg.yaml path or "char1" … "char6".

    Returns
    -------
    dict drawing joint name -> (proximal BVH joint, distal BVH joint).
    """
    motion = load_motion(bvh_motion)
    sk = load_character(skeleton)
    table = _bvh_table(motion.names)
    if table is None:
        raise ValueError("cannot tell the BVH skeleton's naming (expected the AnimatedDrawings "
                         "fair1, cmu1 or rokoko/Mixamo joints); pass mapping={drawing joint: "
                         f"(bvh joint, bvh joint)}} explicitly. BVH joints: {motion.names}")
    out = {n: table[_base_name(n)] for n in sk.names
           if _base_name(n) in table and sk.parents[sk.index(n)] >= 0}
    xy = sk.xy
    if "torso" in out:
        d = xy[sk.index("torso")] - xy[sk.parents[sk.index("torso")]]
        if not -d[1] > abs(d[0]):                 # not drawn upright (y down): a lying body
            del out["torso"]
    if "neck" in out:
        pairs = [(n, "left_" + n[len("right_"):]) for n in sk.names
                 if _base_name(n) == "right_shoulder" and "left_" + n[len("right_"):] in sk.names]
        if pairs:  # the topmost shoulder pair, as six_arms.yaml checks right/left_shoulder3
            r, lft = min(pairs, key=lambda p: xy[sk.index(p[0])][1] + xy[sk.index(p[1])][1])
            t = xy[sk.index(lft)] - xy[sk.index(r)]
            v = xy[sk.index("neck")] - xy[sk.index(r)]
            if t[0] * v[1] - t[1] * v[0] >= 0:    # neck on or below the line (image axes)
                del out["neck"]
    return out


def _check_mapping(mapping, sk, motion):
    """(M,) drawing joint indices and (M, 2) BVH joint indices of a mapping."""
    if not isinstance(mapping, dict):
        raise TypeError(f"mapping must be a dict drawing joint -> (bvh joint, bvh joint), got "
                        f"{type(mapping).__name__}")
    joints, pairs = [], []
    for name, seg in mapping.items():
        if name not in sk.names:
            raise ValueError(f"mapping names the drawing joint {name!r}, which the skeleton "
                             f"does not have; its joints are {list(sk.names)}")
        j = sk.index(name)
        if sk.parents[j] < 0:
            raise ValueError(f"mapping[{name!r}]: the root has no bone to orient; map its "
                             "children instead")
        if (not isinstance(seg, (tuple, list)) or len(seg) != 2
                or not all(isinstance(s, str) for s in seg)):
            raise TypeError(f"mapping[{name!r}] must be a pair (proximal, distal) of BVH joint "
                            f"names, got {seg!r}")
        joints.append(j)
        pairs.append([motion.joint_index(seg[0]), motion.joint_index(seg[1])])
    return np.array(joints, dtype=np.int64), np.array(pairs, dtype=np.int64).reshape(-1, 2)


def _frame_positions(P, frames):
    """World joints ``(F, J, 3)`` at (possibly fractional) frames, linear between frames."""
    T = P.shape[0]
    f = np.asarray(frames, dtype=float)
    i0 = np.clip(np.floor(f).astype(np.int64), 0, max(T - 2, 0))
    w = (f - i0)[:, None, None]
    i1 = np.minimum(i0 + 1, T - 1)
    return (1 - w) * P[i0] + w * P[i1]


def _up_axis(up, P_ref, sk, joints, pairs):
    """(3,) unit up vector: given, or inferred from the mapped trunk (up) and legs (down)."""
    if up is not None:
        if isinstance(up, str):
            if up not in _AXES:
                raise ValueError(f"up must be one of {list(_AXES)} or a 3-vector, got {up!r}")
            return np.array(_AXES[up], dtype=float)
        u = np.asarray(up, dtype=float)
        if u.shape != (3,) or not np.linalg.norm(u) > 0:
            raise ValueError(f"up must be a non-zero 3-vector or one of {list(_AXES)}, got {up!r}")
        return u / np.linalg.norm(u)
    v = np.zeros(3)
    for j, (a, b) in zip(joints, pairs):
        base = _base_name(sk.names[j])
        sign = 1.0 if base in ("torso", "neck") else -1.0 if base.endswith(("_knee", "_foot")) \
            else 0.0
        seg = P_ref[b] - P_ref[a]
        n = np.linalg.norm(seg)
        if sign and n > 0:
            v += sign * seg / n
    if not np.abs(v).max() > 0:
        raise ValueError("cannot infer the BVH's up axis (the mapping has no torso, neck, knee "
                         "or foot joints); pass up='+y' or up='+z'")
    k = int(np.argmax(np.abs(v)))                 # snap to the nearest world axis
    u = np.zeros(3)
    u[k] = np.sign(v[k])
    return u


def _right_vectors(P, sk, joints, pairs, u):
    """(F, 3) unit horizontal vector from the actor's left to right side, per frame.

    Averages ``right - left`` over the proximal BVH joints of mapped left/right limb pairs
    whose drawing parent is not mapped (the upper arms and thighs).
    """
    mapped = {sk.names[j]: pr for j, pr in zip(joints, pairs)}
    v = np.zeros((P.shape[0], 3))
    for name, (a, _) in mapped.items():
        if not name.startswith("left_"):
            continue
        other = "right_" + name[len("left_"):]
        parent = sk.names[sk.parents[sk.index(name)]]
        if other not in mapped or parent in mapped:
            continue
        d = P[:, mapped[other][0]] - P[:, a]                      # (F, 3) left -> right
        n = np.linalg.norm(d, axis=1, keepdims=True)
        v += np.where(n > 0, d / np.where(n > 0, n, 1.0), 0.0)
    v -= (v @ u)[:, None] * u                                     # horizontal part
    n = np.linalg.norm(v, axis=1)
    ok = n > 1e-9
    if not ok.any():
        raise ValueError("cannot tell which way the BVH actor faces: the mapping needs a "
                         "left_*/right_* limb pair (e.g. left_elbow and right_elbow) whose "
                         "proximal BVH joints are apart horizontally")
    if not ok.all():   # frames without a facing (shoulders and hips stacked) take the nearest
        good = np.flatnonzero(ok)
        near = good[np.abs(np.arange(len(v))[:, None] - good[None]).argmin(axis=1)]
        v, n = v[near], n[near]
    return v / n[:, None]


def _segment_views(view, sk, joints, pairs, P, u, r):
    """(M,) bool, True where a mapped segment is projected with the side view.

    ``view="auto"`` follows AnimatedDrawings' ``pca`` projection groups: for the arms
    (``*_elbow*``, ``*_hand*``) and the legs (``*_knee*``, ``*_foot*``) separately, the BVH
    joints of their segments, relative to the BVH root and in the actor's frame (left-right,
    forward, up) over all T frames, are fitted by PCA; if the least-varying direction is closer
    to left-right than to forward, the limbs move in the sagittal plane and are seen from the
    side, else from the front. The trunk is always seen from the front (``frontal``).
    """
    M = len(joints)
    names = [sk.names[j] for j in joints]
    if isinstance(view, dict):
        bad = [n for n in view if n not in names]
        if bad:
            raise ValueError(f"view names joints that are not mapped: {bad}; mapped joints "
                             f"are {names}")
        vals = set(view.values()) - set(_VIEWS)
        if vals:
            raise ValueError(f"view values must be one of {_VIEWS}, got {sorted(map(str, vals))}")
        return np.array([view.get(n, "front") == "side" for n in names], dtype=bool)
    if not isinstance(view, str) or view not in _VIEWS + ("auto",):
        raise ValueError(f"view must be one of {_VIEWS + ('auto',)} or a dict joint -> view, "
                         f"got {view!r}")
    if view != "auto":
        return np.full(M, view == "side")
    side = np.zeros(M, dtype=bool)
    fwd = np.cross(u, r)                                           # (T, 3)
    root = P[:, :1]
    for suffixes in (("_elbow", "_hand"), ("_knee", "_foot")):
        grp = np.array([_base_name(n).endswith(suffixes) for n in names], dtype=bool)
        if not grp.any():
            continue
        X = P[:, np.unique(pairs[grp])] - root                    # (T, k, 3)
        pts = np.stack([np.einsum("tjk,tk->tj", X, r), np.einsum("tjk,tk->tj", X, fwd),
                        X @ u], axis=-1).reshape(-1, 3)           # (T k, 3) actor frame
        pts = pts - pts.mean(axis=0)
        pc3 = np.linalg.svd(pts, full_matrices=False)[2][-1]      # least-varying direction
        side[grp] = abs(pc3[0]) >= abs(pc3[1])
    return side


def _retarget_xy(motion, sk, mapping, frames, view, method, reference_frame, root_motion,
                 follow_turns, up):
    """Posed joint positions ``(F, J, 2)`` (pixels); see :func:`bvh_to_skeletons`."""
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    T = motion.n_frames
    if T == 0:
        raise ValueError("the BVH clip has no frames")
    if frames is None:
        fr = np.arange(T, dtype=float)
    else:
        try:
            fr = np.atleast_1d(np.asarray(frames, dtype=float))
        except (TypeError, ValueError):
            raise TypeError(f"frames must be None, a frame index or a 1D array of frame "
                            f"indices, got {type(frames).__name__}") from None
    if fr.ndim != 1 or not np.all(np.isfinite(fr)):
        raise ValueError("frames must be None, a frame index or a 1D array of finite frame "
                         "indices")
    if fr.size and (fr.min() < 0 or fr.max() > T - 1):
        raise IndexError(f"frames must lie in [0, {T - 1}] (the clip has {T} frames), got "
                         f"[{fr.min():g}, {fr.max():g}]")
    if not (isinstance(reference_frame, (int, np.integer)) and 0 <= reference_frame < T):
        raise IndexError(f"reference_frame must be an integer frame in [0, {T - 1}], got "
                         f"{reference_frame!r}")
    ref = int(reference_frame)
    joints, pairs = _check_mapping(mapping, sk, motion)

    P_all = motion.joint_positions()                              # (T, Jb, 3) file units
    broot = int(np.flatnonzero(motion.parents < 0)[0])
    u = _up_axis(up, P_all[ref], sk, joints, pairs)               # (3,)
    if follow_turns:
        r_all = _right_vectors(P_all, sk, joints, pairs, u)       # (T, 3)
    else:
        r_all = np.repeat(_right_vectors(P_all[ref:ref + 1], sk, joints, pairs, u), T, axis=0)
    side = _segment_views(view, sk, joints, pairs, P_all, u, r_all)   # (M,)

    fr1 = np.concatenate([[ref], fr])                             # ref first, then frames
    P = _frame_positions(P_all, fr1)                              # (1 + F, Jb, 3)
    r = _frame_positions(r_all[:, None], fr1)[:, 0]               # (1 + F, 3)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    # Eq. (1): orthographic projection; screen x = actor's left (front) or forward (side),
    # screen y = -up (pixels are y down)
    ex_front, ex_side = -r, np.cross(u, r)                        # (1 + F, 3)
    y = -(P @ u)                                                  # (1 + F, Jb)
    a, b = pairs[:, 0], pairs[:, 1]
    dxf = np.einsum("fmk,fk->fm", P[:, b] - P[:, a], ex_front)    # (1 + F, M)
    dxs = np.einsum("fmk,fk->fm", P[:, b] - P[:, a], ex_side)
    seg2 = np.stack([np.where(side, dxs, dxf), y[:, b] - y[:, a]], axis=-1)   # (1 + F, M, 2)
    seg3 = np.linalg.norm(P[:, b] - P[:, a], axis=-1)             # (1 + F, M)
    valid = (np.linalg.norm(seg2, axis=-1) > MIN_PROJECTED_FRACTION * seg3) & (seg3 > 0)
    phi = np.arctan2(seg2[..., 1], seg2[..., 0])                 # (1 + F, M) screen angles

    rest_ang = sk.bone_angles()                                   # (J,)
    L = sk.bone_lengths()                                         # (J,)
    if method == "relative":
        target = rest_ang[joints] + _wrap(phi - phi[:1])          # rotation since ref
        valid &= valid[:1]
    else:
        target = phi
    target, valid = target[1:], valid[1:]                         # (F, M)

    # root: drawing root + s * projected BVH root displacement since ref; the horizontal part
    # accumulates each frame's step in that frame's view (AnimatedDrawings), which is the
    # plain projected displacement when the camera is fixed
    F, J = len(fr), len(sk)
    root_xy = np.broadcast_to(sk.xy[sk.root], (F, 2)).copy()
    if root_motion:
        legs = np.array([_base_name(sk.names[j]).endswith(("_knee", "_foot")) for j in joints],
                        dtype=bool)
        root_side = bool(side[legs][0]) if legs.any() else view == "side"
        ex_all = np.cross(u, r_all) if root_side else -r_all     # (T, 3)
        steps = np.einsum("tk,tk->t", np.diff(P_all[:, broot], axis=0), ex_all[1:])
        dx = np.concatenate([[0.0], np.cumsum(steps)])            # (T,)
        d = np.stack([np.interp(fr, np.arange(T), dx) - dx[ref], y[1:, broot] - y[0, broot]],
                     axis=-1)                                     # (F, 2) BVH units
        sel = legs if legs.any() else np.ones(len(joints), dtype=bool)
        bvh_len = np.linalg.norm(P_all[ref, b[sel]] - P_all[ref, a[sel]], axis=-1).sum()
        if bvh_len > 0:
            root_xy += (L[joints[sel]].sum() / bvh_len) * d       # px per BVH unit

    # forward kinematics over the drawing's tree, vectorised over frames
    col = {int(j): m for m, j in enumerate(joints)}
    ang = np.zeros((F, J))
    xy = np.zeros((F, J, 2))
    for j in sk.order:
        p = sk.parents[j]
        if p < 0:
            xy[:, j] = root_xy
            continue
        inherited = rest_ang[j] + (ang[:, p] - rest_ang[p] if sk.parents[p] >= 0 else 0.0)
        if j in col:
            m = col[j]
            ang[:, j] = np.where(valid[:, m], target[:, m], inherited)
        else:
            ang[:, j] = inherited
        xy[:, j] = xy[:, p] + L[j] * np.stack([np.cos(ang[:, j]), np.sin(ang[:, j])], -1)
    return xy, fr


def bvh_to_skeletons(motion, skeleton, mapping=None, frames=None, view="front", *,
                     method="absolute", reference_frame=0, root_motion=True,
                     follow_turns=True, up=None):
    """Pose a drawing's skeleton with BVH frames (AnimatedDrawings-style; module docstring).

    Parameters
    ----------
    motion : BVHMotion, path to a .bvh file, or a name of :data:`ANIMATED_DRAWINGS_MOTIONS`.
    skeleton : Skeleton (pixels, y down), char_cfg.yaml path, or "char1" … "char6".
    mapping : None for :func:`default_mapping`, or dict drawing joint name ->
        (proximal BVH joint, distal BVH joint): the bone into the drawing joint takes the
        direction of the projected BVH segment. Unmapped joints keep their rest local angle.
    frames : None (all T frames), a frame index or (F,) indices in [0, T-1]; fractional
        indices interpolate the BVH world joints linearly (only directions are used).
    view : "front" (camera facing the actor, screen x = actor's left), "side" (camera at the
        actor's left, actor facing screen right), "auto" (arms and legs each seen from the
        front or the side by PCA of their motion, the trunk from the front; AnimatedDrawings'
        ``pca`` groups) or a dict mapped drawing joint -> "front" / "side" (others "front").
    method : "absolute" (bone angle = projected BVH angle, AnimatedDrawings) or "relative"
        (rest angle + BVH rotation since ``reference_frame``).
    reference_frame : int, the BVH frame that fixes the facing direction, the root
        displacement origin and (``method="relative"``) the rest pose.
    root_motion : bool, move the root by the projected BVH root displacement scaled by the
        leg-length ratio (True) or keep it at the drawing's root (False).
    follow_turns : bool, aim the camera at the actor's facing in every frame (default, as
        AnimatedDrawings: a drawing cannot turn, and zombie.bvh turns 180° and back) or only
        at ``reference_frame`` (turns then show, up to the actor's back, mirrored).
    up : None (inferred: the mapped trunk points up, the legs down), "+y", "+z", ... or a
        3-vector, the BVH's up direction.

    Returns
    -------
    list of F Skeletons with ``skeleton``'s names and parents; every bone keeps its length.

    Raises
    ------
    TypeError for a wrong motion / skeleton / mapping type; ValueError for an unknown joint
    in the mapping, an unknown view or method; IndexError for frames out of range.
    """
    motion = load_motion(motion)
    sk = load_character(skeleton)
    if mapping is None:
        mapping = default_mapping(motion, sk)
    xy, _ = _retarget_xy(motion, sk, mapping, frames, view, method, reference_frame,
                         root_motion, follow_turns, up)
    return [sk.with_xy(x) for x in xy]


class KeyframePoses(NamedTuple):
    """Two key poses and the BVH-driven skeletal animation between them."""

    #: Skeleton at BVH frame ``frames[0]``.
    key0: Skeleton
    #: Skeleton at BVH frame ``frames[-1]``.
    key1: Skeleton
    #: list of n Skeletons strictly between the keys.
    inbetweens: list
    #: (n + 2,) float BVH frame indices of key0, the in-betweens and key1.
    frames: np.ndarray


def keyframe_poses(character, motion, f0, f1, n_inbetweens=9, mapping=None, view="front",
                   **kwargs):
    """Two key skeletons at BVH frames ``f0`` and ``f1`` and ``n_inbetweens`` in between.

    The in-betweens sample the BVH uniformly between the keys (``np.linspace(f0, f1,
    n_inbetweens + 2)``, fractional frames interpolated), i.e. the "ground-truth" skeletal
    animation an inbetweening method should reproduce from the two keys.

    Parameters
    ----------
    character : Skeleton, char_cfg.yaml path or "char1" … "char6".
    motion : BVHMotion, .bvh path or a name of :data:`ANIMATED_DRAWINGS_MOTIONS`.
    f0, f1 : frame indices in [0, T-1] (``f1`` may be < ``f0``: the motion backwards).
    n_inbetweens : int ≥ 0.
    mapping, view, **kwargs : as in :func:`bvh_to_skeletons` (``reference_frame`` defaults to
        ``ANIMATED_DRAWINGS_START_FRAMES`` for a named motion, else 0).

    Returns
    -------
    :class:`KeyframePoses` ``(key0, key1, inbetweens, frames)``.
    """
    if not isinstance(n_inbetweens, (int, np.integer)) or n_inbetweens < 0:
        raise ValueError(f"n_inbetweens must be an int ≥ 0, got {n_inbetweens!r}")
    if isinstance(motion, str) and motion in ANIMATED_DRAWINGS_START_FRAMES:
        kwargs.setdefault("reference_frame", ANIMATED_DRAWINGS_START_FRAMES[motion])
    frames = np.linspace(float(f0), float(f1), int(n_inbetweens) + 2)
    sks = bvh_to_skeletons(motion, character, mapping=mapping, frames=frames, view=view,
                           **kwargs)
    return KeyframePoses(sks[0], sks[-1], sks[1:-1], frames)


def bvh_joint_depths(motion, skeleton, mapping=None, frames=None, view="front", *,
                     reference_frame=0, follow_turns=True, up=None):
    """Depth of every drawing joint along the camera axis of :func:`bvh_to_skeletons`.

    The orthographic projection drops the BVH's third axis; this keeps it, so that a limb that
    swings in front of or behind the body has a depth order (``Skeleton.depth``, smaller =
    nearer the viewer; Brodt & Bessmeltsev 2024 Sec. 4 ask for the depths of the joints near
    each occlusion region). The camera is the one of :func:`bvh_to_skeletons`:
    ``view="front"`` looks at the actor's front (depth = ``-P · forward``), ``view="side"`` at
    its left side (depth = ``P · right``), facing followed per frame with ``follow_turns``.

    A mapped drawing joint takes the depth of its distal BVH joint; an unmapped one the
    proximal BVH joint of a mapped child (a shoulder that of ``XArm``, a hip that of
    ``XUpLeg``, the drawing's hip that of ``Hips``), else its parent's depth; the root that of
    the BVH root. Depths are relative to the BVH root in every frame, in BVH file units.

    Parameters
    ----------
    motion, skeleton, mapping, frames, reference_frame, follow_turns, up : as
        :func:`bvh_to_skeletons`.
    view : "front" or "side".

    Returns
    -------
    (F, J) float64 depths, one row per frame, columns in ``skeleton``'s joint order.

    Raises
    ------
    ValueError for another view; the errors of :func:`bvh_to_skeletons` otherwise.
    """
    if not isinstance(view, str) or view not in _VIEWS:
        raise ValueError(f"view must be one of {_VIEWS} for depths, got {view!r}")
    motion = load_motion(motion)
    sk = load_character(skeleton)
    if mapping is None:
        mapping = default_mapping(motion, sk)
    _, fr = _retarget_xy(motion, sk, mapping, frames, view, "absolute", reference_frame,
                         False, follow_turns, up)            # checks frames and the mapping
    joints, pairs = _check_mapping(mapping, sk, motion)
    P_all = motion.joint_positions()                          # (T, Jb, 3)
    ref = int(reference_frame)
    u = _up_axis(up, P_all[ref], sk, joints, pairs)
    r_all = _right_vectors(P_all if follow_turns else P_all[ref:ref + 1], sk, joints, pairs, u)
    if not follow_turns:
        r_all = np.repeat(r_all, len(P_all), axis=0)
    P = _frame_positions(P_all, fr)                           # (F, Jb, 3)
    r = _frame_positions(r_all[:, None], fr)[:, 0]            # (F, 3)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    axis = -np.cross(u, r) if view == "front" else r          # (F, 3) away from the camera
    broot = int(np.flatnonzero(motion.parents < 0)[0])
    d_bvh = np.einsum("fjk,fk->fj", P - P[:, broot:broot + 1], axis)   # (F, Jb)
    src = {int(j): int(b) for j, (_, b) in zip(joints, pairs)}
    for j, (a, _) in zip(joints, pairs):                      # unmapped parent of a mapped joint
        p = int(sk.parents[j])
        if p >= 0 and p not in src:
            src[p] = int(a)
    out = np.zeros((len(fr), len(sk)))
    for j in sk.order:
        p = sk.parents[j]
        out[:, j] = d_bvh[:, src[j]] if j in src else (out[:, p] if p >= 0 else d_bvh[:, broot])
    return out
