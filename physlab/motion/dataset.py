"""Bandai-Namco training windows for a Sketch2Anim-style motion generator.

Data: Bandai-Namco-Research-Motiondataset 1 & 2 as listed by ``labels.csv`` in
``<external data>/mocap/bandai_namco`` (BVH clips at 30 fps, content x style x take: 874 in
the copy of 2026-11 — dataset 1 takes 001–002, dataset 2 takes 001–010; see
``../shared/data/README.md``). Attribution: CC BY-NC 4.0, © 2022 Bandai Namco Research Inc.
(Kobayashi et al. 2023, "Motion Capture Dataset for Practical Use of AI-based Motion Editing
and Stylization"). The clips are read from the external folder and never copied into the
repository.

Pipeline:

1. :func:`load_clips` reads the BVH files and retargets them with
   :func:`~physlab.motion.bvh.retarget_to_smpl22` (:data:`BANDAI_NAMCO_MAPPING`) to
   ``(T, 22, 3)`` joints at 20 fps (metres, y up, lowest foot joint of the clip at
   ``y = 0``), caching the result per clip (:func:`default_cache_dir`);
2. :func:`make_windows` cuts 40-frame (2 s) windows, the Sketch2Anim clip length ``N = 40``,
   each canonicalised (:func:`~physlab.motion.features.canonicalize`), with the text
   :func:`action_text` ("a person waves the right hand happily");
3. :func:`condition_from_window` builds the keypose / trajectory condition of Sketch2Anim
   Sec. 3 from a window;
4. :func:`split_by_take` holds out whole clips (take 002) for testing.
"""
from __future__ import annotations

import csv
import itertools
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab._io import atomic_write

from .bvh import BANDAI_NAMCO_MAPPING, read_bvh, retarget_to_smpl22
from .features import _check_joints, _rotate_y, canonicalize
from .skeleton import JOINT_NAMES, joint_index

__all__ = [
    "BANDAI_NAMCO_ATTRIBUTION", "ACTION_PHRASES", "STYLE_PHRASES", "TRAJECTORY_JOINTS",
    "TRAJECTORY_JOINT_NAMES", "JOINT_COMBINATIONS", "TEST_TAKES", "MotionClip", "Windows",
    "Condition", "bandai_namco_dir", "default_cache_dir", "read_labels", "load_clips",
    "action_text", "make_windows", "condition_from_window", "random_condition",
    "split_by_take", "MIRROR_PERMUTATION", "mirror_joints", "mirror_text", "mirror_windows",
    "turn_windows",
]

BANDAI_NAMCO_ATTRIBUTION = ("Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0, © 2022 Bandai "
                            "Namco Research Inc.")

#: Content label -> verb phrase after "a person" (the Sketch2Anim text template is
#: "a person [action word]", supp. E). ``bye`` waves one hand (the right), ``byebye`` both
#: (measured: left / right wrist height ranges 0.03 / 0.35 m and 0.45 / 0.44 m in the normal
#: clips). The phrases for ``guide``, ``call`` and ``respond`` are read from the label names
#: only (the dataset gives no descriptions); check them against the clips before relying on
#: them.
ACTION_PHRASES = {
    "walk": "walks", "run": "runs", "dash": "dashes forward", "walk-back": "walks backwards",
    "walk-left": "walks to the left", "walk-right": "walks to the right",
    "walk-turn-left": "walks and turns left", "walk-turn-right": "walks and turns right",
    "bow": "bows", "bye": "waves goodbye", "byebye": "waves goodbye with both hands",
    "guide": "gestures the way with an arm", "call": "calls someone over",
    "respond": "responds with a gesture", "punch": "punches", "kick": "kicks",
    "slash": "slashes with a sword", "dance": "dances", "dance-short": "dances",
    "dance-long": "dances", "wave-both-hands": "waves both hands",
    "wave-left-hand": "waves the left hand", "wave-right-hand": "waves the right hand",
    "raise-up-both-hands": "raises both hands", "raise-up-left-hand": "raises the left hand",
    "raise-up-right-hand": "raises the right hand",
}

#: Style label -> adverbial phrase; ``normal`` adds nothing. ``chimpira`` is Japanese for a
#: small-time street thug.
STYLE_PHRASES = {
    "normal": "", "happy": "happily", "sad": "sadly", "angry": "angrily", "proud": "proudly",
    "not-confident": "without confidence", "masculinity": "in a masculine way",
    "masculine": "in a masculine way", "feminine": "in a feminine way",
    "childish": "like a child", "children": "like a child", "old": "like an old person",
    "elderly": "like an elderly person", "tired": "tiredly", "exhausted": "in exhaustion",
    "active": "energetically", "youthful": "youthfully", "musical": "like in a musical",
    "giant": "like a giant", "chimpira": "like a thug",
}

#: The six joints whose trajectories Sketch2Anim conditions on (supp. B): pelvis, left foot,
#: right foot, head, left wrist, right wrist.
TRAJECTORY_JOINT_NAMES = ("pelvis", "left_foot", "right_foot", "head", "left_wrist",
                          "right_wrist")
TRAJECTORY_JOINTS = tuple(JOINT_NAMES.index(n) for n in TRAJECTORY_JOINT_NAMES)  # 0,10,11,15,20,21
#: All 63 non-empty subsets of :data:`TRAJECTORY_JOINTS` (OmniControl's "cross" setting,
#: which Sketch2Anim's evaluation follows, supp. E).
JOINT_COMBINATIONS = tuple(c for k in range(1, 7)
                           for c in itertools.combinations(TRAJECTORY_JOINTS, k))

#: Takes held out by :func:`split_by_take`.
TEST_TAKES = ("002",)

_LABELS = "labels.csv"


# ----------------------------------------------------------------------------- clips


@dataclass(eq=False)
class MotionClip:
    """One retargeted clip.

    Attributes
    ----------
    clip_id : str, the BVH file stem, e.g. ``"dataset-1_walk_happy_001"``.
    dataset, content, style, take : str, from ``labels.csv``.
    joints : (T, 22, 3) float array, metres, y up, lowest foot joint at ``y = 0``; placement
        and facing as in the file.
    fps : float, frame rate of ``joints`` (Hz).
    path : Path of the BVH file.
    """

    clip_id: str
    dataset: str
    content: str
    style: str
    take: str
    joints: np.ndarray = field(repr=False)
    fps: float = 20.0
    path: Path = None

    @property
    def n_frames(self):
        return int(self.joints.shape[0])

    @property
    def text(self):
        """:func:`action_text` of the clip's content and style."""
        return action_text(self.content, self.style)


def bandai_namco_dir(root=None):
    """The Bandai-Namco folder (holding ``labels.csv``).

    ``root`` if given, else ``<external data>/mocap/bandai_namco`` with the external folder
    of :func:`physlab.datasets.external_data_dir`. FileNotFoundError saying what to do if it
    is missing.
    """
    if root is None:
        from physlab.datasets import external_data_dir

        ext = external_data_dir()
        if ext is None:
            raise FileNotFoundError(
                "the external data folder was not found: set PHYSLAB_EXTERNAL_DATA to the "
                "folder holding mocap/bandai_namco, or pass root=<.../mocap/bandai_namco>")
        root = ext / "mocap" / "bandai_namco"
    root = Path(root).expanduser()
    if not (root / _LABELS).is_file():
        raise FileNotFoundError(f"no {_LABELS} in {root}: pass root=<folder of the "
                                f"Bandai-Namco clips holding {_LABELS}> or set "
                                f"PHYSLAB_EXTERNAL_DATA")
    return root


def default_cache_dir():
    """Where :func:`load_clips` caches retargeted clips: ``$PHYSLAB_CACHE_DIR`` if set, else
    ``$XDG_CACHE_HOME/physlab`` (``~/.cache/physlab``). Outside the repository; safe to
    delete."""
    env = os.environ.get("PHYSLAB_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "physlab"


def read_labels(root=None):
    """Rows of ``labels.csv`` as dicts (``file``, ``dataset``, ``content``, ``style``,
    ``take``, ``frames``, ``fps``, ``bytes``, ...), in file order."""
    root = bandai_namco_dir(root)
    with open(root / _LABELS, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


_CACHE_VERSION = 1


def _cache_path(cache_dir, clip_id, fps):
    return Path(cache_dir) / "bandai_namco_smpl22" / f"{clip_id}_{fps:g}fps_v{_CACHE_VERSION}.npz"


def _load_cached(path, source_bytes):
    """The cached joints, or None when the entry is missing, unreadable or stale."""
    try:
        with np.load(path) as z:
            fresh = int(z["source_bytes"]) == source_bytes
            return np.array(z["joints"]) if fresh else None
    except (OSError, KeyError, ValueError):
        return None                            # unreadable cache: recompute


def load_clips(root=None, contents=None, clip_ids=None, fps=20, cache_dir=None,
               progress=False):
    """Read and retarget Bandai-Namco clips to 22-joint positions.

    Each clip is read with :func:`~physlab.motion.bvh.read_bvh` and converted by
    :func:`~physlab.motion.bvh.retarget_to_smpl22` with :data:`BANDAI_NAMCO_MAPPING`
    (30 -> ``fps`` Hz, cm -> m, lowest foot joint at ``y = 0``). The result is cached as
    ``<cache_dir>/bandai_namco_smpl22/<clip_id>_<fps>fps_v1.npz`` (written atomically, keyed
    by the BVH file size); later calls read the cache (~0.4 ms per clip instead of ~11 ms).

    Parameters
    ----------
    root : None or path of the folder holding ``labels.csv`` (see :func:`bandai_namco_dir`).
    contents : None or iterable of content labels (``"walk"``, ``"wave-right-hand"``, ...)
        to keep; ValueError for a label not in ``labels.csv``.
    clip_ids : None or iterable of clip ids (BVH stems) to keep; ValueError if unknown.
    fps : float > 0, output frame rate (Hz); 20 as HumanML3D / Sketch2Anim.
    cache_dir : None (:func:`default_cache_dir`), a path, or False (no caching).
    progress : bool, show a tqdm progress bar.

    Returns
    -------
    list of :class:`MotionClip` in ``labels.csv`` order.
    """
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    root = bandai_namco_dir(root)
    rows = read_labels(root)
    if contents is not None:
        contents = {contents} if isinstance(contents, str) else set(contents)
        known = {r["content"] for r in rows}
        if contents - known:
            raise ValueError(f"unknown contents {sorted(contents - known)}; labels.csv has "
                             f"{', '.join(sorted(known))}")
        rows = [r for r in rows if r["content"] in contents]
    if clip_ids is not None:
        clip_ids = [clip_ids] if isinstance(clip_ids, str) else list(clip_ids)
        by_id = {Path(r["file"]).stem: r for r in rows}
        missing = [c for c in clip_ids if c not in by_id]
        if missing:
            raise ValueError(f"unknown clip ids {missing[:5]} (ids are BVH file stems such as "
                             f"'dataset-1_walk_normal_001'{' within the given contents' if contents else ''})")
        keep = set(clip_ids)
        rows = [r for r in rows if Path(r["file"]).stem in keep]
    if cache_dir is None:
        cache_dir = default_cache_dir()
    from tqdm.auto import tqdm

    clips = []
    for r in tqdm(rows, desc="bandai-namco clips", disable=not progress):
        path = root / r["file"]
        clip_id = path.stem
        if not path.is_file():
            raise FileNotFoundError(f"{path} is listed in {root / _LABELS} but missing")
        size = path.stat().st_size
        joints = None
        if cache_dir:
            cpath = _cache_path(cache_dir, clip_id, fps)
            if cpath.is_file():
                joints = _load_cached(cpath, size)
        if joints is None:
            joints = retarget_to_smpl22(read_bvh(path), BANDAI_NAMCO_MAPPING, fps=fps)
            if cache_dir:
                atomic_write(cpath, lambda tmp, j=joints, n=size: np.savez(
                    tmp, joints=j, fps=float(fps), source_bytes=n), suffix=".npz")
        clips.append(MotionClip(clip_id=clip_id, dataset=r["dataset"], content=r["content"],
                                style=r["style"], take=r["take"], joints=joints,
                                fps=float(fps), path=path))
    return clips


# ----------------------------------------------------------------------------- text


def action_text(content, style=None):
    """Text of a clip: ``"a person <verb phrase>[ <style adverb>]"``.

    ``action_text("walk")`` -> ``"a person walks"``; ``action_text("walk", "happy")`` ->
    ``"a person walks happily"``; style ``None`` or ``"normal"`` adds nothing. The verb
    phrases are :data:`ACTION_PHRASES`, the adverbs :data:`STYLE_PHRASES` (Sketch2Anim supp.
    E: the template "a person [action word]").
    """
    if content not in ACTION_PHRASES:
        raise ValueError(f"unknown content {content!r}; expected one of "
                         f"{', '.join(ACTION_PHRASES)}")
    text = f"a person {ACTION_PHRASES[content]}"
    if style is not None:
        if style not in STYLE_PHRASES:
            raise ValueError(f"unknown style {style!r}; expected one of "
                             f"{', '.join(STYLE_PHRASES)}")
        if STYLE_PHRASES[style]:
            text += f" {STYLE_PHRASES[style]}"
    return text


# ----------------------------------------------------------------------------- windows


@dataclass(eq=False)
class Windows:
    """Fixed-length training windows.

    Attributes
    ----------
    joints : (N, L, 22, 3) float array, each window canonicalised: frame 0 pelvis at
        ``x = z = 0`` facing ``+z``; heights as in the (grounded) clip.
    text : list of N str, :func:`action_text` with style.
    content, style : list of N str, the raw labels (``content`` is the action word).
    clip_id : list of N str.
    start : (N,) int array, first frame of the window in its clip.
    fps : float (Hz).
    """

    joints: np.ndarray = field(repr=False)
    text: list
    content: list
    style: list
    clip_id: list
    start: np.ndarray
    fps: float = 20.0

    def __len__(self):
        return int(self.joints.shape[0])

    @property
    def length(self):
        """Frames per window L."""
        return int(self.joints.shape[1])


def make_windows(clips, length=40, stride=10, drop_short=True):
    """Cut clips into canonicalised windows of ``length`` frames.

    Window starts are ``0, stride, 2 stride, ...`` while the window fits in the clip. Each
    window is moved by :func:`~physlab.motion.features.canonicalize` with ``ground=False``
    (the clips are already grounded; a window in the air stays in the air).

    Parameters
    ----------
    clips : list of :class:`MotionClip` (or of ``(T, 22, 3)`` arrays, given ids
        ``"clip<k>"``, empty text and labels).
    length : int >= 2, frames per window; 40 = 2 s at 20 fps, Sketch2Anim's ``N``.
    stride : int >= 1, frames between window starts (default 10 = 0.5 s, 75 % overlap).
    drop_short : bool, skip clips shorter than ``length`` (default) or raise ValueError.

    Returns
    -------
    :class:`Windows`. ValueError if no clip is long enough.
    """
    length, stride = int(length), int(stride)
    if length < 2 or stride < 1:
        raise ValueError(f"need length >= 2 and stride >= 1, got length={length}, "
                         f"stride={stride}")
    if isinstance(clips, (MotionClip, np.ndarray)):
        clips = [clips]
    out = {"joints": [], "text": [], "content": [], "style": [], "clip_id": [], "start": []}
    fps, longest = None, 0
    for k, c in enumerate(clips):
        if isinstance(c, MotionClip):
            x, meta = c.joints, (c.text, c.content, c.style, c.clip_id)
            clip_fps = c.fps
        else:
            x, meta, clip_fps = c, ("", "", "", f"clip{k}"), 20.0
        x = _check_joints(x, name=f"clip {meta[3]}")
        if fps is None:
            fps = clip_fps
        elif clip_fps != fps:
            raise ValueError(f"clips have different frame rates ({fps} and {clip_fps} Hz); "
                             f"load them with one fps")
        longest = max(longest, len(x))
        if len(x) < length:
            if drop_short:
                continue
            raise ValueError(f"window length {length} > clip {meta[3]} length {len(x)} "
                             f"frames; use a shorter length or drop_short=True")
        starts = np.arange(0, len(x) - length + 1, stride)
        idx = starts[:, None] + np.arange(length)                            # (n, L)
        for s, w in zip(starts, x[idx]):
            out["joints"].append(canonicalize(w, ground=False))
            for key, v in zip(("text", "content", "style", "clip_id"), meta):
                out[key].append(v)
            out["start"].append(int(s))
    if not out["joints"]:
        raise ValueError(f"window length {length} > every clip length (longest "
                         f"{longest} frames); use a shorter length")
    return Windows(joints=np.stack(out["joints"]), text=out["text"], content=out["content"],
                   style=out["style"], clip_id=out["clip_id"],
                   start=np.array(out["start"], dtype=int), fps=float(fps))


# ----------------------------------------------------------------------------- mirroring


def _mirror_permutation():
    """Index of each joint's mirror image (``left_x`` <-> ``right_x``; others themselves)."""
    swap = {"left": "right", "right": "left"}
    perm = []
    for name in JOINT_NAMES:
        side, _, rest = name.partition("_")
        perm.append(JOINT_NAMES.index(f"{swap[side]}_{rest}") if side in swap else
                    JOINT_NAMES.index(name))
    return tuple(perm)


#: ``joints[..., MIRROR_PERMUTATION, :]`` swaps the left and right joints.
MIRROR_PERMUTATION = _mirror_permutation()


def mirror_joints(joints):
    """Mirror image of windows in the canonical frame: ``x -> -x`` and left / right joints
    swapped (:data:`MIRROR_PERMUTATION`); the facing direction ``+z`` is kept. joints :
    (..., 22, 3) array or torch tensor; returns the same type and shape (no torch import
    here: a tensor is recognised by its ``new_tensor`` method)."""
    sign = [-1.0, 1.0, 1.0]
    if hasattr(joints, "new_tensor"):
        return joints[..., list(MIRROR_PERMUTATION), :] * joints.new_tensor(sign)
    x = np.asarray(joints)
    return x[..., list(MIRROR_PERMUTATION), :] * np.asarray(sign, dtype=x.dtype)


_LEFT_RIGHT = re.compile(r"\b(left|right)\b")


def mirror_text(text):
    """The text (or content label) of the mirrored motion: the words "left" and "right"
    swapped ("a person waves the left hand" -> "a person waves the right hand",
    ``"walk-left"`` -> ``"walk-right"``); other texts unchanged."""
    return _LEFT_RIGHT.sub(lambda m: "right" if m.group(1) == "left" else "left", text)


def mirror_windows(windows):
    """The windows followed by their mirror images (mirror augmentation).

    Each mirrored window is :func:`mirror_joints` of the original (still canonical: frame 0
    pelvis at the origin facing ``+z``), with :func:`mirror_text` of its text and content
    ("walks to the left" becomes "walks to the right", a right-hand wave a left-hand wave)
    and ``clip_id + "/mirror"``. Returns a new :class:`Windows` of twice the length."""
    if not isinstance(windows, Windows):
        raise TypeError(f"windows must be a Windows (make_windows), got "
                        f"{type(windows).__name__}")
    return Windows(joints=np.concatenate([windows.joints, mirror_joints(windows.joints)]),
                   text=list(windows.text) + [mirror_text(t) for t in windows.text],
                   content=list(windows.content) + [mirror_text(c) for c in windows.content],
                   style=list(windows.style) * 2,
                   clip_id=list(windows.clip_id) + [f"{c}/mirror" for c in windows.clip_id],
                   start=np.concatenate([windows.start, windows.start]), fps=windows.fps)


def turn_windows(windows, max_degrees=90.0, seed=0):
    """The windows followed by turned copies (turn augmentation, physlab's; not in Sketch2Anim).

    Copy ``i`` turns progressively by ``θ_i ~ U(−max_degrees, max_degrees)`` over the window:
    frame ``t`` of ``L`` is turned by ``θ_i t / (L − 1)`` about the vertical through its pelvis
    (the facing of :func:`~physlab.motion.evaluate.facing` grows by that angle), and the pelvis
    path is re-integrated from its steps turned by the same angle, so the copy walks where it
    faces; frame 0, heights and step lengths are kept, texts too. A toe swings round the pelvis
    by at most the frame's turn times its reach (a few mm per frame), so the copies skate about
    as little as the originals. Measured on held-out windows
    (``docs/motion_experiments.md``, "Where the pose error sits"): the text of a Bandai-Namco
    window implies its turn, so networks trained without this follow a last-frame keypose's
    facing only about a third of the way; with it (90°) more than half of the way, though
    their clips then skate and jerk more.

    Parameters
    ----------
    windows : :class:`Windows`; max_degrees : float in (0, 180]; seed : int, seeds the angles.

    Returns
    -------
    A new :class:`Windows` of twice the length (copies' ``clip_id`` end in ``"/turned"``).
    """
    if not isinstance(windows, Windows):
        raise TypeError(f"windows must be a Windows (make_windows), got "
                        f"{type(windows).__name__}")
    if (isinstance(max_degrees, bool) or not isinstance(max_degrees, (int, float))
            or not 0 < max_degrees <= 180):
        raise ValueError(f"max_degrees must be a number in (0, 180], got {max_degrees!r}")
    J = np.asarray(windows.joints, dtype=float)
    n, L = J.shape[:2]
    rng = np.random.default_rng(seed)
    th = (np.radians(rng.uniform(-max_degrees, max_degrees, n))[:, None]
          * np.linspace(0.0, 1.0, L)[None])                                  # (n, L)
    pelvis = J[:, :, :1] * np.array([1.0, 0.0, 1.0])                        # (n, L, 1, 3) x, z
    out = _rotate_y((J - pelvis).reshape(n * L, -1, 3), th.ravel()).reshape(J.shape)
    steps = _rotate_y(np.diff(pelvis[:, :, 0], axis=1).reshape(-1, 3), th[:, 1:].ravel())
    path = np.cumsum(np.concatenate([pelvis[:, :1, 0], steps.reshape(n, L - 1, 3)], axis=1),
                     axis=1)                                                 # (n, L, 3)
    out += path[:, :, None]
    return Windows(joints=np.concatenate([J, out]), text=list(windows.text) * 2,
                   content=list(windows.content) * 2, style=list(windows.style) * 2,
                   clip_id=list(windows.clip_id) + [f"{c}/turned" for c in windows.clip_id],
                   start=np.concatenate([windows.start, windows.start]), fps=windows.fps)


# ----------------------------------------------------------------------------- conditions


@dataclass(eq=False)
class Condition:
    """Keypose and trajectory condition of one window (Sketch2Anim Sec. 3).

    Attributes
    ----------
    keypose : (22, 3) float array, the window's pose at ``key_frame`` (window coordinates).
    key_frame : int, 0 (stroke starts at its joint) or ``N - 1`` (stroke ends there).
    trajectory : (N, 6, 3) float array, positions of the :data:`TRAJECTORY_JOINTS` where
        ``mask`` is True, 0 elsewhere.
    mask : (N, 6) bool array, True on the first / last ``t_r`` frames of the chosen joints.
    joints : tuple of int, the chosen joints (indices into :data:`JOINT_NAMES`).
    t_r : int, frames covered by the trajectories.
    """

    keypose: np.ndarray
    key_frame: int
    trajectory: np.ndarray
    mask: np.ndarray
    joints: tuple
    t_r: int

    def generator_kwargs(self):
        """This condition as the ``keypose_3d`` / ``keypose_at`` / ``trajectories_3d``
        arguments of :func:`physlab.motion.generate` (each trajectory the ``(t_r, 3)`` points
        of its masked frames, metres) — how the evaluation and the lessons pass it."""
        trajs = {name: self.trajectory[self.mask[:, c], c]                    # (t_r, 3)
                 for c, name in enumerate(TRAJECTORY_JOINT_NAMES) if self.mask[:, c].any()}
        return {"keypose_3d": self.keypose, "trajectories_3d": trajs,
                "keypose_at": "first" if self.key_frame == 0 else "last"}

    @property
    def keypose_dense(self):
        """``K_3D``: (N, 22, 3) float, the keypose at ``key_frame`` and 0 elsewhere."""
        K = np.zeros((len(self.mask), len(JOINT_NAMES), 3))
        K[self.key_frame] = self.keypose
        return K


def _trajectory_columns(joints):
    """Column of each requested joint (name or index) in :data:`TRAJECTORY_JOINTS`."""
    if isinstance(joints, (str, int, np.integer)):
        joints = [joints]
    cols = []
    for j in joints:
        if isinstance(j, str):
            if j not in JOINT_NAMES:
                raise ValueError(f"unknown joint {j!r}; trajectories are defined for "
                                 f"{', '.join(TRAJECTORY_JOINT_NAMES)}")
            j = joint_index(j)
        if int(j) not in TRAJECTORY_JOINTS:
            name = JOINT_NAMES[int(j)] if 0 <= int(j) < len(JOINT_NAMES) else j
            raise ValueError(f"joint {name!r} has no trajectory condition; use some of "
                             f"{', '.join(TRAJECTORY_JOINT_NAMES)} (indices "
                             f"{TRAJECTORY_JOINTS})")
        cols.append(TRAJECTORY_JOINTS.index(int(j)))
    if not cols:
        raise ValueError("joints is empty; give at least one trajectory joint")
    return sorted(set(cols))


def condition_from_window(window, t_r=None, keypose_at="first", joints=TRAJECTORY_JOINTS):
    """The keypose / trajectory condition of Sketch2Anim Sec. 3 ("Feature representation").

    Fill rule: if the trajectory stroke *starts* at its joint (``keypose_at="first"``), the
    keypose is frame 1 of the window (index 0) and the trajectories fill the *first*
    ``t_r`` frames; if the stroke *ends* at its joint (``"last"``), the keypose is frame
    ``N`` (index ``N - 1``) and the trajectories fill the *last* ``t_r`` frames. The
    trajectory of joint ``j`` over those frames is the window's own positions of ``j`` (the
    3D surrogate ``T^r_3D`` used in training). Choosing the window so that its first / last
    frame is the representative keypose (Sketch2Anim picks it with TMR, supp. B) is left to
    the caller.

    Parameters
    ----------
    window : (N, 22, 3) float array (e.g. one of :attr:`Windows.joints`).
    t_r : None or int in ``1 .. N``, frames covered by the strokes; None = ``N``.
    keypose_at : ``"first"`` or ``"last"``.
    joints : names or indices of joints with a stroke, a non-empty subset of
        :data:`TRAJECTORY_JOINTS` (default: all six).

    Returns
    -------
    :class:`Condition` (keypose ``(22, 3)``, key frame, trajectory ``(N, 6, 3)``, mask
    ``(N, 6)``).
    """
    x = _check_joints(window, name="window")
    N = len(x)
    if t_r is None:
        t_r = N
    if not float(t_r).is_integer() or not 1 <= int(t_r) <= N:
        raise ValueError(f"t_r must be an integer in 1..{N} (the window length), got {t_r}")
    t_r = int(t_r)
    if keypose_at not in ("first", "last"):
        raise ValueError(f"keypose_at must be 'first' or 'last', got {keypose_at!r}")
    cols = _trajectory_columns(joints)
    key_frame = 0 if keypose_at == "first" else N - 1
    frames = np.arange(t_r) if keypose_at == "first" else np.arange(N - t_r, N)
    mask = np.zeros((N, len(TRAJECTORY_JOINTS)), dtype=bool)
    mask[np.ix_(frames, cols)] = True
    trajectory = np.where(mask[..., None], x[:, list(TRAJECTORY_JOINTS)], 0.0)   # (N, 6, 3)
    return Condition(keypose=x[key_frame].copy(), key_frame=key_frame, trajectory=trajectory,
                     mask=mask, joints=tuple(TRAJECTORY_JOINTS[c] for c in cols), t_r=t_r)


def random_condition(window, rng, min_t_r=5, single_joint=0.0):
    """A random training condition: keypose at the first or last frame (p = 1/2), one of
    the 63 :data:`JOINT_COMBINATIONS` (uniform; with probability ``single_joint`` one of the
    six single joints instead, uniform) and ``t_r`` uniform in ``min_t_r .. N``.

    Parameters
    ----------
    window : (N, 22, 3) float array.
    rng : numpy Generator (``np.random.default_rng(seed)``).
    min_t_r : int in ``1 .. N``.
    single_joint : float in [0, 1], extra share of single-joint strokes (the "Average"
        protocol's conditions; uniform over the 63 combinations they are 6 / 63 ≈ 10 %).

    Returns
    -------
    :class:`Condition`.
    """
    N = len(np.asarray(window))
    if not 1 <= int(min_t_r) <= N:
        raise ValueError(f"min_t_r must lie in 1..{N}, got {min_t_r}")
    if not 0.0 <= float(single_joint) <= 1.0:
        raise ValueError(f"single_joint must be a probability in [0, 1], got {single_joint}")
    t_r = int(rng.integers(min_t_r, N + 1))
    keypose_at = "first" if rng.random() < 0.5 else "last"
    combo = JOINT_COMBINATIONS[int(rng.integers(len(JOINT_COMBINATIONS)))]
    if single_joint and rng.random() < single_joint:    # drawn after the others: with
        combo = (TRAJECTORY_JOINTS[int(rng.integers(len(TRAJECTORY_JOINTS)))],)  # p = 0 the
    return condition_from_window(window, t_r=t_r, keypose_at=keypose_at,        # stream is as
                                 joints=combo)                                   # before


# ----------------------------------------------------------------------------- split


def split_by_take(clips, test_takes=TEST_TAKES):
    """Split clips into train / test by take, holding out whole clips.

    Default: test = take ``"002"``. Every take-002 clip (88 of the 874 of 2026-11: 70 of
    dataset 2, and walk / call / punch / slash of dataset 1) is another performance of a
    (dataset, content, style) whose take 001 stays in training, so the test measures
    generalisation to a new performance of known actions and styles, and no content or
    style is missing from training. It holds out 11 % of the frames. Windows of one clip
    never straddle the split because whole clips are assigned.

    Parameters
    ----------
    clips : list of :class:`MotionClip`.
    test_takes : iterable of take strings (``"001"``, ``"002"``) to hold out.

    Returns
    -------
    (train, test) : two lists of :class:`MotionClip`.
    """
    test_takes = {test_takes} if isinstance(test_takes, str) else set(test_takes)
    known = {c.take for c in clips}
    if test_takes - known and known:
        raise ValueError(f"no clip has take {sorted(test_takes - known)}; the takes are "
                         f"{sorted(known)}")
    train = [c for c in clips if c.take not in test_takes]
    test = [c for c in clips if c.take in test_takes]
    return train, test
