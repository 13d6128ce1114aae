"""A keyframe pair on disk: the folder ``physlab evaluate inbetween --pairs DIR`` reads.

One's own triplet (two keys, their skeletons, and in-betweens drawn by hand) is evaluated
like the procedural benchmark (:mod:`physlab.inbetween.evaluate`, the analogue of
Brodt & Bessmeltsev 2024, Table 1) once it is laid out as :data:`FOLDER_FORMAT` says.
:func:`load_pair_folder` reads and checks everything, and names the file and what is wrong
in every error; :meth:`PairFolder.truth_frames` places the ground truth on the frame times.
:func:`read_skeleton` is also what ``physlab inbetween --skeleton0`` reads.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .skeleton import Skeleton, check_compatible

__all__ = ["FOLDER_FORMAT", "PairFolder", "load_pair_folder", "read_skeleton",
           "skeleton_from_dict", "DEFAULT_FRAMES"]

FOLDER_FORMAT = """\
DIR/
  key0.png, key1.png         the keyframes, same size: RGBA (a transparent background; gaps
                             inside the figure become holes of its mesh) or RGB / grey on
                             light paper
  skeleton0.json,            their skeletons, Skeleton.to_dict(): {"names": [...],
  skeleton1.json             "parents": [...] (-1 for the root), "xy": [[x, y], ...] (pixels,
                             y down, inside the image), optional "depth": [...]}; same joints
  gt_<t>.png (optional)      a true in-between at time t in (0, 1), e.g. gt_0.5.png,
                             gt_0.25.png, gt_0.333.png: t is a frame's time written within
                             0.001 (and within the rounding of its last decimal); same size
                             as the keys
  animation.json (optional)  the skeletal motion: a list of skeleton dicts, one per frame,
                             keys included (n_frames = its length); default: bone-angle
                             interpolation between the keys
  occlusions0.json,          occlusion regions of each key, as physlab.inbetween.
  occlusions1.json           save_occlusions writes them: {"occlusions": [{"polygon": [[x, y],
  (optional)                 ...], "t_junctions": [[x, y], ...], "label": "..."}, ...]}; with
                             either file both keys get layered templates (occlusion layers)
Frames (keys included) without --frames: the length of animation.json, else 11, or the
smallest count above 11 whose times linspace(0, 1, n) include every gt_<t>.png."""

#: Frames (keys included) when neither ``n_frames`` nor an animation file says otherwise.
DEFAULT_FRAMES = 11
#: Largest difference between a ``gt_<t>.png``'s t and its frame's time.
TIME_TOLERANCE = 1e-3
#: Files every pair folder has.
REQUIRED = ("key0.png", "key1.png", "skeleton0.json", "skeleton1.json")
#: Fields of a skeleton dict (:meth:`Skeleton.to_dict`): required, then optional.
SKELETON_FIELDS = ("names", "parents", "xy")
SKELETON_OPTIONAL = ("depth",)
_GT = re.compile(r"^gt_(?P<t>[0-9]*\.?[0-9]+)\.png$")


def _read_json(path, what):
    """Parsed JSON of ``path``; ValueError naming the file and the position of a syntax error."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise ValueError(f"{what}: not a text (JSON) file") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{what}: not valid JSON ({e.msg} at line {e.lineno}, column "
                         f"{e.colno})") from None


def skeleton_from_dict(d, where="skeleton"):
    """A :class:`~physlab.inbetween.Skeleton` from its :meth:`~Skeleton.to_dict` form.

    Parameters
    ----------
    d : dict with "names" (J str), "parents" (J int, −1 for the root), "xy" (J × 2 pixels)
        and optionally "depth" (J floats or null).
    where : str naming the source in error messages (a file, ``animation.json[3]`` ...).

    Returns
    -------
    Skeleton.

    Raises
    ------
    ValueError naming ``where``: not a dict, missing or unknown fields, or what
    :class:`Skeleton` rejects (lengths, parents, NaN ...).
    """
    fields = "{" + ", ".join(f'"{k}"' for k in SKELETON_FIELDS) + \
        ", optional " + ", ".join(f'"{k}"' for k in SKELETON_OPTIONAL) + "}"
    if not isinstance(d, dict):
        raise ValueError(f"{where}: a skeleton must be a JSON object {fields}, got "
                         f"{type(d).__name__}")
    missing = [k for k in SKELETON_FIELDS if k not in d]
    unknown = sorted(set(d) - set(SKELETON_FIELDS) - set(SKELETON_OPTIONAL))
    if missing or unknown:
        what = ([f"missing field(s) {missing}"] if missing else []) + \
               ([f"unknown field(s) {unknown}"] if unknown else [])
        raise ValueError(f"{where}: {'; '.join(what)}; a skeleton is {fields} in pixels, y "
                         f"down (Skeleton.to_dict())")
    depth = {} if d.get("depth") is None else {"depth": d["depth"]}
    try:
        return Skeleton(d["names"], d["parents"], d["xy"], **depth)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{where}: {e}") from None


def read_skeleton(path, name=None):
    """Read a skeleton file: JSON (:meth:`Skeleton.to_dict`) or an AnimatedDrawings
    ``char_cfg.yaml``.

    Parameters
    ----------
    path : str or Path.
    name : str or None, what the file is in error messages (e.g. ``"--skeleton0"``).

    Returns
    -------
    Skeleton (pixels, y down).

    Raises
    ------
    FileNotFoundError naming the file; ValueError naming it for invalid JSON or a bad
    skeleton (:func:`skeleton_from_dict`).
    """
    path = Path(path)
    where = f"{name} {path}" if name else str(path)
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no such file")
    if path.suffix.lower() in (".yaml", ".yml"):
        return Skeleton.from_animated_drawings(path)
    return skeleton_from_dict(_read_json(path, where), where)


def _decimals(text):
    """Number of decimals written in a number, e.g. 2 for "0.25"."""
    return len(text.split(".")[1]) if "." in text else 0


def _matches(t, tol, n):
    """(m,) frame index of each time ``t`` on ``linspace(0, 1, n)`` within ``tol``, −1 if none."""
    i = np.rint(np.asarray(t) * (n - 1)).astype(int)
    return np.where(np.abs(i / (n - 1) - np.asarray(t)) <= np.asarray(tol), i, -1)


@dataclass
class PairFolder:
    """A keyframe pair read from a folder (:data:`FOLDER_FORMAT`).

    Attributes
    ----------
    path : Path of the folder.
    key0, key1 : (H, W[, C]) images as stored (uint8 / uint16).
    skeleton0, skeleton1 : Skeletons of the keys.
    truth : dict t → (H, W[, C]) image, the ground-truth in-betweens (may be empty).
    truth_tolerance : dict t → float, how far t may be from its frame's time: 0.001, or
        half a unit of the last decimal written in the name if that is less.
    truth_files : dict t → file name (``gt_<t>.png``).
    animation : list of Skeletons (keys included) or None.
    occlusions : (list of Occlusion or None, list of Occlusion or None), key 0 and key 1
        (None: no file), for ``inbetween(occlusions0=..., occlusions1=...)``.
    """

    path: Path
    key0: np.ndarray
    key1: np.ndarray
    skeleton0: Skeleton
    skeleton1: Skeleton
    truth: dict = field(default_factory=dict)
    truth_tolerance: dict = field(default_factory=dict)
    truth_files: dict = field(default_factory=dict)
    animation: list = None
    occlusions: tuple = (None, None)

    @property
    def name(self):
        """The folder's name."""
        return self.path.name

    def n_frames(self, requested=None):
        """Frames to make, keys included (the rule at the end of :data:`FOLDER_FORMAT`).

        ``requested`` : int ≥ 3 or None. ValueError when it disagrees with animation.json
        or leaves a ground-truth time off the frame times (the message suggests a count)."""
        from .pipeline import MAX_FRAMES

        if requested is not None:
            if isinstance(requested, bool) or not isinstance(requested, (int, np.integer)) \
                    or requested < 3:
                raise ValueError(f"n_frames must be an integer >= 3 (both keys and at least "
                                 f"one in-between), got {requested!r}")
            requested = int(requested)
        if self.animation is not None:
            if requested is not None and requested != len(self.animation):
                raise ValueError(f"{self.path / 'animation.json'} has {len(self.animation)} "
                                 f"skeletons but {requested} frames were asked for; drop "
                                 f"--frames or give one skeleton per frame")
            n = len(self.animation)
        else:
            n = requested
        if n is not None:
            self.truth_frames(n)  # every ground truth on a frame time, or a clear error
            return n
        n = self._fitting_frames(DEFAULT_FRAMES)
        if n is None:
            raise ValueError(f"no frame count up to {MAX_FRAMES} puts every ground truth "
                             f"{sorted(self.truth_files.values())} of {self.path} on a frame "
                             f"time; write the times with fewer decimals")
        return n

    def truth_frames(self, n_frames):
        """Ground truth by frame index: dict ``i → image`` for the frames of
        ``linspace(0, 1, n_frames)`` that have one. ValueError naming the file of a time that
        is no frame time."""
        out = {}
        for t, img in self.truth.items():
            i = int(_matches([t], [self.truth_tolerance[t]], n_frames)[0])
            if i < 0:
                good = self._nearest_fitting_frames(n_frames)
                raise ValueError(f"{self.path / self.truth_files[t]}: t = {t:g} is not a frame "
                                 f"time of linspace(0, 1, {n_frames}) (step "
                                 f"{1 / (n_frames - 1):.4g})" +
                                 (f"; use {good} frames" if good else "") +
                                 " or rename the file to a frame's time")
            if i in out:
                raise ValueError(f"{self.path}: two ground-truth files fall on frame {i} "
                                 f"(t = {i / (n_frames - 1):.4g}) of {n_frames}; keep one")
            out[i] = img
        return dict(sorted(out.items()))

    def _fitting(self):
        """(k,) every frame count (3..``MAX_FRAMES``) whose frame times include every
        ground-truth time, increasing."""
        from .pipeline import MAX_FRAMES

        t = list(self.truth)
        tol = [self.truth_tolerance[s] for s in t]
        return np.array([n for n in range(3, MAX_FRAMES + 1) if (_matches(t, tol, n) >= 0).all()],
                        dtype=int)

    def _fitting_frames(self, start):
        """Smallest fitting frame count ≥ ``start`` (:meth:`_fitting`), or None."""
        fits = self._fitting()
        fits = fits[fits >= start]
        return int(fits[0]) if len(fits) else None

    def _nearest_fitting_frames(self, near):
        """The fitting frame count nearest to ``near`` (the smaller on a tie), or None."""
        fits = self._fitting()
        return int(fits[np.argmin(np.abs(fits - near))]) if len(fits) else None


def load_pair_folder(path):
    """Read and check a keyframe-pair folder (layout: :data:`FOLDER_FORMAT`).

    Parameters
    ----------
    path : str or Path of the folder.

    Returns
    -------
    PairFolder.

    Raises
    ------
    FileNotFoundError for a missing folder or missing required files (all named at once);
    NotADirectoryError for a file; ValueError naming the file for an unreadable image, keys
    of different sizes, a skeleton file with wrong fields, skeletons of different joints,
    joints outside the image, a ``gt_*.png`` whose name is no time in (0, 1) or whose size
    differs from the keys', an animation of another topology, invalid JSON, occlusion files
    that :func:`~physlab.inbetween.occlusion.load_occlusions` rejects.
    """
    from ..image import read_image
    from .occlusion import load_occlusions
    from .template import _check_joints_in_image

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"pair folder {path}: no such folder")
    if not path.is_dir():
        raise NotADirectoryError(f"pair folder {path}: not a folder (give the folder that "
                                 f"holds {', '.join(REQUIRED)})")
    missing = [f for f in REQUIRED if not (path / f).is_file()]
    if missing:
        raise FileNotFoundError(f"pair folder {path}: missing {', '.join(missing)} (a pair "
                                f"folder holds {', '.join(REQUIRED)}, optionally gt_<t>.png, "
                                f"animation.json, occlusions0/1.json)")
    keys = [read_image(path / f"key{k}.png", f"key{k}") for k in (0, 1)]
    if keys[0].shape[:2] != keys[1].shape[:2]:
        raise ValueError(f"{path / 'key0.png'} is {keys[0].shape[1]}x{keys[0].shape[0]} px but "
                         f"{path / 'key1.png'} is {keys[1].shape[1]}x{keys[1].shape[0]}; the "
                         f"keys must have the same size (resize or pad one)")
    shape = keys[0].shape[:2]
    sks = [read_skeleton(path / f"skeleton{k}.json") for k in (0, 1)]
    check_compatible(sks[0], sks[1], (str(path / "skeleton0.json"), str(path / "skeleton1.json")))
    for k, sk in enumerate(sks):
        _check_joints_in_image(sk, shape, str(path / f"skeleton{k}.json"))

    truth, tolerance, names = {}, {}, {}
    for f in sorted(path.glob("gt*.png")):
        m = _GT.match(f.name)
        t = float(m["t"]) if m else None
        if t is None or not 0.0 < t < 1.0:
            raise ValueError(f"{f}: a ground-truth file is named gt_<t>.png with t the frame's "
                             f"time strictly between 0 and 1 (the keys are t = 0 and 1), e.g. "
                             f"gt_0.5.png")
        if t in truth:
            raise ValueError(f"{f} and {path / names[t]} give the same time t = {t:g}")
        img = read_image(f, "ground truth")
        if img.shape[:2] != shape:
            raise ValueError(f"{f} is {img.shape[1]}x{img.shape[0]} px but the keys are "
                             f"{shape[1]}x{shape[0]}; ground truth must have the keys' size")
        truth[t], names[t] = img, f.name
        tolerance[t] = min(TIME_TOLERANCE, 0.5 * 10.0 ** -_decimals(m["t"])) + 1e-12

    animation = None
    if (path / "animation.json").is_file():
        where = str(path / "animation.json")
        data = _read_json(path / "animation.json", where)
        if not isinstance(data, list) or len(data) < 3:
            raise ValueError(f"{where}: must be a JSON list of skeleton dicts, one per frame "
                             f"with both keys (at least 3), got "
                             f"{type(data).__name__ if not isinstance(data, list) else len(data)}")
        animation = [skeleton_from_dict(d, f"{where}[{i}]") for i, d in enumerate(data)]
        for i, sk in enumerate(animation):
            check_compatible(sks[0], sk, (str(path / "skeleton0.json"), f"{where}[{i}]"))

    occlusions = tuple(load_occlusions(path / f"occlusions{k}.json")
                       if (path / f"occlusions{k}.json").is_file() else None for k in (0, 1))
    return PairFolder(path=path, key0=keys[0], key1=keys[1], skeleton0=sks[0],
                      skeleton1=sks[1], truth=dict(sorted(truth.items())),
                      truth_tolerance=tolerance, truth_files=names, animation=animation,
                      occlusions=occlusions)
