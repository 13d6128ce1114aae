"""BVH motion files: read, write, forward kinematics and retargeting to the 22-joint skeleton.

A BVH file [Biovision; Meredith & Maddock 2001, "Motion capture file formats explained"]
has a ``HIERARCHY`` of joints (``ROOT`` / ``JOINT`` blocks with an ``OFFSET`` in the
parent's frame and a list of ``CHANNELS``; leaves end with an ``End Site``) and a ``MOTION``
block: ``Frames: T``, ``Frame Time: dt`` and ``T`` lines of ``C`` channel values.

Conventions used here (the common ones; Blender's and Holden's ``BVH.py`` agree):

* rotation channels are degrees, applied as *intrinsic* rotations in the order they are
  listed, ``R = R_{c0} R_{c1} R_{c2}`` (see :func:`physlab.motion.skeleton.euler_to_matrix`);
* position channels *replace* the matching component of the joint's ``OFFSET`` (so the root's
  ``Xposition Yposition Zposition`` are its world position, and inner joints with six
  channels — as in the Bandai-Namco files — get their per-frame translation from them);
* end sites are kept as extra joints named ``"<parent>_End"`` with their offset and no
  channels (``read_bvh(path, end_sites=False)`` drops them); :func:`write_bvh` writes such a
  joint back as an ``End Site``.

:func:`retarget_to_smpl22` turns a BVH clip into HumanML3D-style joint positions
``(T', 22, 3)`` in metres, y up, feet on the ground, resampled to ``fps`` (20 by default, the
HumanML3D / Sketch2Anim rate). :data:`BANDAI_NAMCO_MAPPING`, :data:`CMU_MAPPING` and
:data:`CMU_MAX_MAPPING` give the joint correspondences and unit scales of the mocap clips in
the external data folder (``../shared/data/mocap``):

* Bandai-Namco Research Motiondataset 1 & 2: centimetres (``scale = 0.01``); every joint has
  six channels whose positions equal the offsets (rigid bones).
  Attribution: CC BY-NC 4.0, © 2022 Bandai Namco Research Inc.
* CMU (cgspeed BVH conversions, MotionBuilder- and 3dsMax-friendly releases): CMU skeleton
  units, ``metres = units * (1 / 0.45) * 2.54 / 100`` (mocap.cs.cmu.edu FAQ), i.e.
  ``scale = 0.05644``. "The data used in this project was obtained from mocap.cs.cmu.edu. The
  database was created with funding from NSF EIA-0196217."
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab._io import atomic_write_text

from .skeleton import FOOT_JOINTS, JOINT_NAMES, euler_to_matrix, forward_kinematics

__all__ = [
    "BVHMotion", "read_bvh", "write_bvh", "SMPL22Mapping", "retarget_to_smpl22",
    "resample_local", "BANDAI_NAMCO_MAPPING", "CMU_MAPPING", "CMU_MAX_MAPPING", "CMU_SCALE",
]

#: Canonical channel names, keyed by their lower-case spelling.
_CHANNELS = {c.lower(): c for c in (
    "Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")}

#: CMU skeleton units to metres (mocap.cs.cmu.edu FAQ): units * (1 / 0.45) * 2.54 / 100.
CMU_SCALE = (1.0 / 0.45) * 2.54 / 100


#: Deepest joint hierarchy accepted (a chain this long is no skeleton; deeper would exhaust
#: Python's recursion in the parser and writer).
MAX_DEPTH = 256
#: Accepted ``Frame Time`` range (s): 10 kHz .. one frame a minute.
FRAME_TIME_RANGE = (1e-4, 60.0)
#: Largest number of frames :func:`resample_local` produces.
MAX_RESAMPLED_FRAMES = 2_000_000


def _depths(parents):
    """(J,) depth of every joint (roots 0) of a parents-before-children array."""
    d = np.zeros(len(parents), dtype=int)
    for j, p in enumerate(parents):
        if p >= 0:
            d[j] = d[p] + 1
    return d


def _channel_columns(channels):
    """Start column of each joint's channels in the motion matrix, and the total count C."""
    counts = [len(c) for c in channels]
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int) if counts else []
    return starts, int(sum(counts))


@dataclass(eq=False)
class BVHMotion:
    """A BVH clip: skeleton hierarchy and raw channel values.

    Attributes
    ----------
    names : list of J str, joint names (end sites, when kept, are named ``"<parent>_End"``).
    parents : (J,) int array, parent index of each joint, -1 for roots; parents come before
        their children (file order).
    offsets : (J, 3) float array, ``OFFSET`` of each joint in its parent's frame (file units).
    channels : list of J lists of str, the joint's channel names in file order, canonical
        spelling (``"Xposition"``, ``"Zrotation"``, ...); empty for end sites.
    frame_time : float, seconds per frame (> 0).
    motion : (T, C) float array, channel values per frame (rotations in degrees, positions
        in file units), columns ordered joint by joint as in ``channels``.
    """

    names: list
    parents: np.ndarray
    offsets: np.ndarray
    channels: list
    frame_time: float
    motion: np.ndarray = field(repr=False)

    def __post_init__(self):
        self.names = [str(n) for n in self.names]
        J = len(self.names)
        self.parents = np.asarray(self.parents, dtype=int).reshape(-1)
        self.offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        if self.parents.shape != (J,) or self.offsets.shape != (J, 3) or len(self.channels) != J:
            raise ValueError(f"names ({J}), parents {self.parents.shape}, offsets "
                             f"{self.offsets.shape} and channels ({len(self.channels)}) must "
                             f"describe the same number of joints")
        if np.any(self.parents >= np.arange(J)) or np.any(self.parents < -1):
            raise ValueError(f"parents must satisfy -1 <= parents[j] < j (parents before "
                             f"children), got {self.parents.tolist()}")
        channels = []
        for name, chans in zip(self.names, self.channels):
            canon = []
            for c in chans:
                if str(c).lower() not in _CHANNELS:
                    raise ValueError(f"joint {name!r}: unknown channel {c!r}; expected one of "
                                     f"{', '.join(_CHANNELS.values())}")
                canon.append(_CHANNELS[str(c).lower()])
            channels.append(canon)
        self.channels = channels
        lo, hi = FRAME_TIME_RANGE
        if not (isinstance(self.frame_time, (int, float, np.number))
                and lo <= self.frame_time <= hi):
            raise ValueError(f"frame_time must be in [{lo:g}, {hi:g}] s, got {self.frame_time}")
        self.frame_time = float(self.frame_time)
        if J and _depths(self.parents).max() > MAX_DEPTH:
            raise ValueError(f"the hierarchy is {_depths(self.parents).max() + 1} joints deep, "
                             f"more than the {MAX_DEPTH + 1} physlab reads")
        if not np.all(np.isfinite(self.offsets)):
            j = int(np.flatnonzero(~np.isfinite(self.offsets).all(1))[0])
            raise ValueError(f"joint {self.names[j]!r} has a non-finite OFFSET "
                             f"{self.offsets[j].tolist()}")
        _, C = _channel_columns(self.channels)
        motion = np.asarray(self.motion, dtype=float)
        if motion.ndim == 1 and motion.size == 0:
            motion = motion.reshape(0, C)
        if motion.ndim != 2 or motion.shape[1] != C:
            raise ValueError(f"motion must have shape (T, {C}) — one column per channel of the "
                             f"hierarchy — got {motion.shape}")
        if not np.all(np.isfinite(motion)):
            t, c = np.argwhere(~np.isfinite(motion))[0]
            raise ValueError(f"motion holds NaN or inf (first at frame {t}, channel column "
                             f"{c}); fix the data before using or writing it")
        self.motion = motion

    @property
    def n_frames(self):
        """Number of frames T."""
        return self.motion.shape[0]

    @property
    def n_joints(self):
        """Number of joints J (including kept end sites)."""
        return len(self.names)

    @property
    def fps(self):
        """Frames per second, ``1 / frame_time``."""
        return 1.0 / self.frame_time

    @property
    def duration(self):
        """Time from the first to the last frame (s), ``(T - 1) * frame_time``."""
        return max(self.n_frames - 1, 0) * self.frame_time

    def joint_index(self, name):
        """Index of the joint called ``name``; ValueError listing the joints if absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"no joint {name!r} in this BVH; its joints are "
                             f"{', '.join(self.names)}") from None

    def rotations(self):
        """Local joint rotations, ``(T, J, 3, 3)`` float, from each joint's rotation channels
        in the order they appear in the file (intrinsic, degrees); identity for joints
        without rotation channels."""
        T, J = self.n_frames, self.n_joints
        R = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
        starts, _ = _channel_columns(self.channels)
        groups = {}  # axis order -> (joint indices, motion columns); one euler call per order
        for j, chans in enumerate(self.channels):
            cols = [starts[j] + k for k, c in enumerate(chans) if c.endswith("rotation")]
            if cols:
                order = "".join(chans[c - starts[j]][0] for c in cols)
                groups.setdefault(order, ([], []))
                groups[order][0].append(j)
                groups[order][1].append(cols)
        for order, (joints, cols) in groups.items():
            R[:, joints] = euler_to_matrix(self.motion[:, np.array(cols)], order)  # (T, k, 3, 3)
        return R

    def translations(self):
        """Local joint translations, ``(T, J, 3)`` float (file units): the ``OFFSET`` with
        the components given by position channels replaced by their values."""
        t = np.broadcast_to(self.offsets, (self.n_frames, self.n_joints, 3)).copy()
        starts, _ = _channel_columns(self.channels)
        for j, chans in enumerate(self.channels):
            for k, c in enumerate(chans):
                if c.endswith("position"):
                    t[:, j, "XYZ".index(c[0])] = self.motion[:, starts[j] + k]
        return t

    def root_positions(self):
        """World position of the (first) root joint in every frame, ``(T, 3)`` float (file
        units): its position channels, or its offset where it has none."""
        root = int(np.flatnonzero(self.parents < 0)[0])
        return self.translations()[:, root]

    def joint_positions(self, scale=1.0):
        """World positions of all joints by forward kinematics, ``(T, J, 3)`` float, in file
        units times ``scale`` (e.g. ``scale=0.01`` for a file in centimetres -> metres)."""
        return scale * forward_kinematics(self.rotations(), self.translations(), self.parents)


# ----------------------------------------------------------------------------- reading


def _tokens(lines):
    """(token, line number) pairs of the hierarchy lines; braces are separate tokens."""
    out = []
    for lineno, line in lines:
        for tok in line.replace("{", " { ").replace("}", " } ").split():
            out.append((tok, lineno))
    return out


class _Parser:
    """Recursive-descent parser of the HIERARCHY block (Meredith & Maddock 2001, Sec. 2)."""

    def __init__(self, path, tokens, end_sites):
        self.path, self.tokens, self.i, self.end_sites = path, tokens, 0, end_sites
        self.names, self.parents, self.offsets, self.channels = [], [], [], []
        self.last_line = tokens[-1][1] if tokens else 1

    def error(self, msg, lineno=None):
        if lineno is None:
            lineno = self.tokens[self.i][1] if self.i < len(self.tokens) else self.last_line
        return ValueError(f"{self.path}: line {lineno}: {msg}")

    def next(self, what):
        if self.i >= len(self.tokens):
            raise self.error(f"unexpected end of the hierarchy, expected {what}")
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def expect(self, word):
        tok, lineno = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.error(f"expected {word!r}, got {tok!r}", lineno)

    def number(self, what, kind=float):
        tok, lineno = self.next(what)
        try:
            v = kind(tok)
        except ValueError:
            raise self.error(f"expected {what}, got {tok!r}", lineno) from None
        if not np.isfinite(v):
            raise self.error(f"{what} must be a finite number, got {tok!r}", lineno)
        return v

    def joint(self, parent, depth=0):
        """Parse a ROOT/JOINT block after its keyword; returns nothing, appends to lists."""
        kw_line = self.tokens[self.i - 1][1]
        if depth > MAX_DEPTH:
            raise self.error(f"the hierarchy is more than {MAX_DEPTH + 1} joints deep; "
                             f"physlab reads at most {MAX_DEPTH + 1} (is a '}}' missing?)",
                             kw_line)
        name_parts = []
        while (self.i < len(self.tokens) and self.tokens[self.i][1] == kw_line
               and self.tokens[self.i][0] not in "{}"):
            name_parts.append(self.tokens[self.i][0])
            self.i += 1
        if not name_parts:
            raise self.error("joint without a name", kw_line)
        j = len(self.names)
        self.names.append(" ".join(name_parts))
        self.parents.append(parent)
        self.offsets.append(None)
        self.channels.append([])
        self.expect("{")
        while True:
            tok, lineno = self.next("OFFSET, CHANNELS, JOINT, End Site or '}'")
            key = tok.upper()
            if key == "OFFSET":
                self.offsets[j] = [self.number("an OFFSET coordinate") for _ in range(3)]
            elif key == "CHANNELS":
                n = self.number("the number of channels", int)
                chans = []
                for _ in range(n):
                    c, cl = self.next("a channel name")
                    if c.lower() not in _CHANNELS:
                        raise self.error(f"unknown channel {c!r} (CHANNELS {n} declared); "
                                         f"expected one of {', '.join(_CHANNELS.values())}", cl)
                    chans.append(_CHANNELS[c.lower()])
                self.channels[j] = chans
            elif key == "JOINT":
                self.joint(j, depth + 1)
            elif key == "END":
                self.expect("Site")
                self.expect("{")
                self.expect("OFFSET")
                off = [self.number("an End Site OFFSET coordinate") for _ in range(3)]
                self.expect("}")
                if self.end_sites:
                    name = f"{self.names[j]}_End"
                    while name in self.names:
                        name += "_"
                    self.names.append(name)
                    self.parents.append(j)
                    self.offsets.append(off)
                    self.channels.append([])
            elif key == "}":
                break
            else:
                raise self.error(f"unexpected {tok!r} in joint {self.names[j]!r}; expected "
                                 f"OFFSET, CHANNELS, JOINT, End Site or '}}'", lineno)
        if self.offsets[j] is None:
            raise self.error(f"joint {self.names[j]!r} has no OFFSET", kw_line)

    def hierarchy(self):
        self.expect("HIERARCHY")
        while self.i < len(self.tokens):
            self.expect("ROOT")
            self.joint(-1)
        if not self.names:
            raise self.error("the HIERARCHY has no ROOT joint")


_FRAMES = re.compile(r"^\s*frames\s*:\s*(\S+)\s*$", re.IGNORECASE)
_FRAME_TIME = re.compile(r"^\s*frame\s+time\s*:\s*(\S+)\s*$", re.IGNORECASE)


def read_bvh(path, end_sites=True):
    """Read a BVH file.

    Accepts any hierarchy (several roots too), 0–6 channels per joint in any order, any
    Euler order, tabs / spaces / CRLF / braces on the joint line, and upper- or lower-case
    keywords and channel names.

    Parameters
    ----------
    path : str or Path.
    end_sites : bool, keep ``End Site`` s as joints named ``"<parent>_End"`` (default) or
        drop them.

    Returns
    -------
    :class:`BVHMotion`. Raises ValueError naming the file and line for malformed input
    (unknown keyword or channel, missing OFFSET, wrong number of values in a frame, frame
    count different from ``Frames:``, ...).
    """
    path = Path(path)
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = f.read().splitlines()
    numbered = [(k + 1, line) for k, line in enumerate(lines) if line.strip()]
    motion_at = next((k for k, (_, line) in enumerate(numbered)
                      if line.split()[0].upper() == "MOTION"), None)
    if motion_at is None:
        raise ValueError(f"{path}: line {len(lines)}: no MOTION section; is this a BVH file?")
    parser = _Parser(path, _tokens(numbered[:motion_at]), end_sites)
    parser.hierarchy()
    _, C = _channel_columns(parser.channels)

    def header(k, pattern, what, kind):
        if k >= len(numbered):
            raise ValueError(f"{path}: line {len(lines)}: missing '{what}' after MOTION")
        lineno, line = numbered[k]
        m = pattern.match(line)
        try:
            if m is None:
                raise ValueError
            return kind(m.group(1))
        except ValueError:
            raise ValueError(f"{path}: line {lineno}: expected '{what} <value>', got "
                             f"{line.strip()!r}") from None

    n_frames = header(motion_at + 1, _FRAMES, "Frames:", int)
    frame_time = header(motion_at + 2, _FRAME_TIME, "Frame Time:", float)
    lo, hi = FRAME_TIME_RANGE
    if n_frames < 0:
        raise ValueError(f"{path}: line {numbered[motion_at + 1][0]}: Frames must be >= 0, got "
                         f"{n_frames}")
    if not lo <= frame_time <= hi:                      # NaN fails this too
        raise ValueError(f"{path}: line {numbered[motion_at + 2][0]}: Frame Time must be in "
                         f"[{lo:g}, {hi:g}] s (e.g. 0.0333333 for 30 fps), got {frame_time}")
    data = numbered[motion_at + 3:]
    if C == 0:
        data, motion = [], np.zeros((n_frames, 0))
    if len(data) != n_frames and C > 0:
        lineno = data[n_frames][0] if len(data) > n_frames else len(lines)
        raise ValueError(f"{path}: line {lineno}: the file declares Frames: {n_frames} but has "
                         f"{len(data)} frame lines")
    if C > 0:
        for lineno, line in data:
            if len(line.split()) != C:
                raise ValueError(f"{path}: line {lineno}: expected {C} channel values (the "
                                 f"hierarchy's channel count), got {len(line.split())}")
        try:
            motion = np.array(" ".join(line for _, line in data).split(), dtype=float)
        except ValueError:
            for lineno, line in data:
                for tok in line.split():
                    try:
                        float(tok)
                    except ValueError:
                        raise ValueError(f"{path}: line {lineno}: {tok!r} is not a number") \
                            from None
            raise
        motion = motion.reshape(n_frames, C)
        bad = ~np.isfinite(motion)
        if bad.any():
            t, c = np.argwhere(bad)[0]
            raise ValueError(f"{path}: line {data[t][0]}: value {c + 1} is "
                             f"{data[t][1].split()[c]!r}; frame values must be finite numbers")
    return BVHMotion(names=parser.names, parents=np.array(parser.parents, dtype=int),
                     offsets=np.array(parser.offsets, dtype=float).reshape(-1, 3),
                     channels=parser.channels, frame_time=frame_time, motion=motion)


# ----------------------------------------------------------------------------- writing


def _fmt(values):
    return " ".join(f"{v:.10g}" for v in values)


def _is_end_site(m, j, children):
    p = m.parents[j]
    return p >= 0 and not m.channels[j] and not children[j] and m.names[j].startswith(
        m.names[p] + "_End")


def write_bvh(path, motion):
    """Write a :class:`BVHMotion` as a BVH file (atomically: temp file + ``os.replace``).

    Joints named ``"<parent>_End"`` with no channels and no children are written as
    ``End Site`` blocks; values are written with 10 significant digits, so
    ``read_bvh(write_bvh(p, m))`` reproduces ``m`` to ~1e-9 relative.

    Parameters
    ----------
    path : str or Path, the file to (over)write.
    motion : :class:`BVHMotion`.
    """
    m = motion
    if not (np.all(np.isfinite(m.motion)) and np.all(np.isfinite(m.offsets))):
        raise ValueError(f"cannot write {path}: the motion or the offsets hold NaN or inf")
    children = [[] for _ in m.names]
    for j, p in enumerate(m.parents):
        if p >= 0:
            children[p].append(j)
    out = ["HIERARCHY"]

    def emit(j, depth):
        ind = "\t" * depth
        if _is_end_site(m, j, children):
            out.extend([f"{ind}End Site", f"{ind}{{", f"{ind}\tOFFSET {_fmt(m.offsets[j])}",
                        f"{ind}}}"])
            return
        out.append(f"{ind}{'ROOT' if m.parents[j] < 0 else 'JOINT'} {m.names[j]}")
        out.append(f"{ind}{{")
        out.append(f"{ind}\tOFFSET {_fmt(m.offsets[j])}")
        out.append(f"{ind}\tCHANNELS {len(m.channels[j])} {' '.join(m.channels[j])}".rstrip())
        for c in children[j]:
            emit(c, depth + 1)
        out.append(f"{ind}}}")

    for r in np.flatnonzero(m.parents < 0):
        emit(int(r), 0)
    out += ["MOTION", f"Frames: {m.n_frames}", f"Frame Time: {m.frame_time:.10g}"]
    text = "\n".join(out) + "\n"
    if m.motion.shape[1] > 0:
        text += "\n".join(_fmt(row) for row in m.motion) + "\n"
    return atomic_write_text(path, text)


# ----------------------------------------------------------------------------- resampling


def _quat_slerp(q0, q1, w):
    """Spherical linear interpolation of unit quaternions ``(N, 4)`` with weights ``(N,)``."""
    d = np.sum(q0 * q1, axis=-1)
    q1 = np.where(d[:, None] < 0, -q1, q1)            # shortest arc
    d = np.clip(np.abs(d), 0.0, 1.0)
    theta = np.arccos(d)
    s = np.sin(theta)
    small = s < 1e-8
    s_safe = np.where(small, 1.0, s)
    a = np.where(small, 1 - w, np.sin((1 - w) * theta) / s_safe)
    b = np.where(small, w, np.sin(w * theta) / s_safe)
    q = a[:, None] * q0 + b[:, None] * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def resample_local(motion, fps):
    """Local rotations and translations of a BVH clip resampled to ``fps``.

    Frame ``k`` of the result is at time ``k / fps`` (``k = 0 .. floor(duration * fps)``);
    rotations are interpolated by slerp of each joint's local rotation and translations
    linearly, so forward kinematics of the result keeps every bone rigid (interpolating
    joint *positions* instead would shorten fast-turning bones by up to a few mm).

    Parameters
    ----------
    motion : :class:`BVHMotion` with ``T >= 1`` frames.
    fps : float > 0, target frame rate (Hz).

    Returns
    -------
    rotations : (T', J, 3, 3) float; translations : (T', J, 3) float (file units).
    """
    from scipy.spatial.transform import Rotation

    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a finite number > 0, got {fps}")
    T, J = motion.n_frames, motion.n_joints
    if T == 0:
        raise ValueError("the BVH clip has no frames")
    R, t = motion.rotations(), motion.translations()
    if T == 1:
        return R, t
    n_new = int(np.floor(motion.duration * fps + 1e-6)) + 1
    if n_new > MAX_RESAMPLED_FRAMES:
        raise ValueError(f"resampling {motion.duration:g} s at {fps:g} fps would make {n_new:,} "
                         f"frames, more than the limit of {MAX_RESAMPLED_FRAMES:,}; check the "
                         f"file's Frame Time or use a lower fps")
    u = np.arange(n_new) / fps / motion.frame_time          # (T',) source frame coordinate
    i0 = np.clip(np.floor(u).astype(int), 0, T - 2)
    w = np.clip(u - i0, 0.0, 1.0)
    t_new = (1 - w)[:, None, None] * t[i0] + w[:, None, None] * t[i0 + 1]
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(T, J, 4)
    q_new = _quat_slerp(q[i0].reshape(-1, 4), q[i0 + 1].reshape(-1, 4), np.repeat(w, J))
    R_new = Rotation.from_quat(q_new).as_matrix().reshape(n_new, J, 3, 3)
    return R_new, t_new


# ----------------------------------------------------------------------------- retargeting


@dataclass(frozen=True)
class SMPL22Mapping:
    """How a BVH skeleton maps onto the 22 joints of :data:`JOINT_NAMES`.

    Attributes
    ----------
    joints : dict, SMPL joint name -> BVH joint name, or ``("mid", a, b)`` for the midpoint
        of BVH joints ``a`` and ``b``; all 22 names must be present.
    scale : float, metres per BVH length unit.
    source : str, which data the mapping is for.
    """

    joints: dict
    scale: float
    source: str = ""


#: Bandai-Namco Research Motiondataset 1 & 2 (22-joint skeleton, cm); ``joint_Root`` unused.
BANDAI_NAMCO_MAPPING = SMPL22Mapping(
    joints={
        "pelvis": "Hips", "left_hip": "UpperLeg_L", "right_hip": "UpperLeg_R", "spine1": "Spine",
        "left_knee": "LowerLeg_L", "right_knee": "LowerLeg_R", "spine2": "Chest",
        "left_ankle": "Foot_L", "right_ankle": "Foot_R", "spine3": ("mid", "Chest", "Neck"),
        "left_foot": "Toes_L", "right_foot": "Toes_R", "neck": "Neck",
        "left_collar": "Shoulder_L", "right_collar": "Shoulder_R", "head": "Head",
        "left_shoulder": "UpperArm_L", "right_shoulder": "UpperArm_R",
        "left_elbow": "LowerArm_L", "right_elbow": "LowerArm_R",
        "left_wrist": "Hand_L", "right_wrist": "Hand_R",
    },
    scale=0.01,
    source="Bandai-Namco-Research-Motiondataset (centimetres)",
)

#: CMU, MotionBuilder-friendly cgspeed release (01_01, 02_01, 05_06: Hips, LHipJoint,
#: LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase, LowerBack, Spine, Spine1, Neck, Neck1, Head,
#: LeftShoulder, LeftArm, LeftForeArm, LeftHand, ...). ``LowerBack``, ``Neck`` and
#: ``*Shoulder`` have zero offsets (they sit on ``Hips`` and ``Spine1``), so the README hint
#: (spine1 = LowerBack, spine2 = Spine1, spine3 = Neck, collar = *Shoulder) would give
#: zero-length pelvis-spine1 and spine3-collar bones. Instead every SMPL bone joins two
#: points fixed in one BVH joint's frame, so bones stay rigid and non-degenerate:
#: spine1 = Spine, spine2 = midpoint(Spine, Spine1), spine3 = Neck (= Spine1's position),
#: neck = Neck1, collar = midpoint(*Shoulder, *Arm).
CMU_MAPPING = SMPL22Mapping(
    joints={
        "pelvis": "Hips", "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg", "spine1": "Spine",
        "left_knee": "LeftLeg", "right_knee": "RightLeg", "spine2": ("mid", "Spine", "Spine1"),
        "left_ankle": "LeftFoot", "right_ankle": "RightFoot", "spine3": "Neck",
        "left_foot": "LeftToeBase", "right_foot": "RightToeBase", "neck": "Neck1",
        "left_collar": ("mid", "LeftShoulder", "LeftArm"),
        "right_collar": ("mid", "RightShoulder", "RightArm"), "head": "Head",
        "left_shoulder": "LeftArm", "right_shoulder": "RightArm",
        "left_elbow": "LeftForeArm", "right_elbow": "RightForeArm",
        "left_wrist": "LeftHand", "right_wrist": "RightHand",
    },
    scale=CMU_SCALE,
    source="CMU mocap, cgspeed MotionBuilder-friendly BVH (CMU units, 0.05644 m)",
)

#: CMU, 3dsMax-friendly cgspeed release (131_*, AnimatedDrawings' cmu1/jumping_jacks: Hips,
#: LHipJoint, LeftHip, LeftKnee, LeftAnkle, LeftToe, lowerback, Chest, Chest2, lowerneck,
#: Neck, Head, LeftCollar, LeftShoulder, LeftElbow, LeftWrist, ...). ``lowerback``,
#: ``lowerneck`` and ``*Collar`` have zero offsets; handled as in :data:`CMU_MAPPING`.
CMU_MAX_MAPPING = SMPL22Mapping(
    joints={
        "pelvis": "Hips", "left_hip": "LeftHip", "right_hip": "RightHip", "spine1": "Chest",
        "left_knee": "LeftKnee", "right_knee": "RightKnee", "spine2": ("mid", "Chest", "Chest2"),
        "left_ankle": "LeftAnkle", "right_ankle": "RightAnkle", "spine3": "lowerneck",
        "left_foot": "LeftToe", "right_foot": "RightToe", "neck": "Neck",
        "left_collar": ("mid", "LeftCollar", "LeftShoulder"),
        "right_collar": ("mid", "RightCollar", "RightShoulder"), "head": "Head",
        "left_shoulder": "LeftShoulder", "right_shoulder": "RightShoulder",
        "left_elbow": "LeftElbow", "right_elbow": "RightElbow",
        "left_wrist": "LeftWrist", "right_wrist": "RightWrist",
    },
    scale=CMU_SCALE,
    source="CMU mocap, cgspeed 3dsMax-friendly BVH (CMU units, 0.05644 m)",
)


def _resolve_mapping(motion, mapping):
    """``[(i, i), ...]`` per SMPL joint: the BVH joint indices whose midpoint it is."""
    missing = [n for n in JOINT_NAMES if n not in mapping]
    if missing:
        raise ValueError(f"mapping lacks the SMPL joints {', '.join(missing)}")
    extra = sorted(set(mapping) - set(JOINT_NAMES))
    if extra:
        raise ValueError(f"mapping has unknown SMPL joint names {extra}; expected "
                         f"{', '.join(JOINT_NAMES)}")
    pairs = []
    for n in JOINT_NAMES:
        src = mapping[n]
        if isinstance(src, str):
            pairs.append((motion.joint_index(src),) * 2)
        elif isinstance(src, (tuple, list)) and len(src) == 3 and src[0] == "mid":
            pairs.append((motion.joint_index(src[1]), motion.joint_index(src[2])))
        else:
            raise ValueError(f"mapping[{n!r}] must be a BVH joint name or ('mid', a, b), "
                             f"got {src!r}")
    return np.array(pairs)


def retarget_to_smpl22(bvh_motion, mapping, scale=None, fps=20, y_up=True):
    """HumanML3D-style joint positions ``(T', 22, 3)`` (metres, y up) from a BVH clip.

    Steps: resample the local rotations / translations to ``fps`` (:func:`resample_local`),
    forward kinematics, pick (or average, for ``("mid", a, b)``) the mapped joints, scale to
    metres, rotate z-up data to y-up if needed, and shift vertically so that the lowest
    ankle / foot joint over the whole clip is at ``y = 0``. The horizontal position is
    left as in the file.

    Parameters
    ----------
    bvh_motion : :class:`BVHMotion`.
    mapping : :class:`SMPL22Mapping` (e.g. :data:`BANDAI_NAMCO_MAPPING`, :data:`CMU_MAPPING`,
        :data:`CMU_MAX_MAPPING`) or a dict SMPL joint name -> BVH joint name or
        ``("mid", a, b)``.
    scale : None or float, metres per BVH unit; None takes ``mapping.scale`` (required for a
        plain dict).
    fps : float > 0, output frame rate (Hz); ``T' = floor(duration * fps) + 1``.
    y_up : bool, True if the BVH world is y-up (Bandai, CMU); False for z-up data, which is
        rotated by -90° about x: ``(x, y, z) -> (x, z, -y)``.

    Returns
    -------
    (T', 22, 3) float array, joints in :data:`JOINT_NAMES` order, metres.
    """
    joints = mapping.joints if isinstance(mapping, SMPL22Mapping) else dict(mapping)
    if scale is None:
        if not isinstance(mapping, SMPL22Mapping):
            raise ValueError("scale (metres per BVH unit, e.g. 0.01 for centimetres) is "
                             "required when mapping is a plain dict")
        scale = mapping.scale
    if not scale > 0:
        raise ValueError(f"scale must be > 0, got {scale}")
    pairs = _resolve_mapping(bvh_motion, joints)                   # (22, 2)
    R, t = resample_local(bvh_motion, fps)                         # (T', J, 3, 3), (T', J, 3)
    x = forward_kinematics(R, t, bvh_motion.parents)               # (T', J, 3) file units
    out = 0.5 * scale * (x[:, pairs[:, 0]] + x[:, pairs[:, 1]])   # (T', 22, 3) metres
    if not y_up:
        out = out[..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0])
    out[..., 1] -= out[:, list(FOOT_JOINTS), 1].min()
    return out
