"""Keypose and trajectory conditions of one generated clip, checked and laid out
(Sketch2Anim Sec. 3): 3D conditions for the networks and the guidance
(:func:`build_condition`), 2D ones drawn in a camera view (:func:`build_sketch`).

Pure numpy, so that storyboards and widgets can validate what a person gives without
importing torch; :mod:`physlab.motion.sampling` re-exports both builders.
"""
from __future__ import annotations

import math

import numpy as np

from .dataset import TRAJECTORY_JOINT_NAMES, TRAJECTORY_JOINTS
from .skeleton import JOINT_NAMES

__all__ = ["N_FRAMES", "KEYPOSE_AT", "MAX_GUIDANCE", "GUIDANCE_SPLIT", "build_condition",
           "build_sketch", "check_trajectories", "check_guidance", "guidance_at",
           "format_guidance", "guidance_argument"]

#: Joint frames of a generated clip (Sketch2Anim N = 40).
N_FRAMES = 40
#: Where the keypose sits: frame 0 (trajectories over the first t_r frames) or frame N - 1.
KEYPOSE_AT = ("first", "last")


def _finite_array(x, name, shape=None):
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as e:
        raise TypeError(f"{name} must be a numeric array, got {type(x).__name__} ({e})") from None
    if shape is not None and a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")
    return a



def check_trajectories(trajectories, name, dim, N, keypose_at):
    """Validate a ``{joint_name: (t_r, dim) array}`` dict and place it in an ``(N, 6, dim)``
    array (the first ``t_r`` frames, or the last with ``keypose_at="last"``) with its
    ``(N, 6)`` mask."""
    trajectory = np.zeros((N, len(TRAJECTORY_JOINTS), dim))
    mask = np.zeros((N, len(TRAJECTORY_JOINTS)), dtype=bool)
    if trajectories is None:
        return trajectory, mask
    if not isinstance(trajectories, dict):
        raise TypeError(f"{name} must be a dict {{joint_name: (t_r, {dim}) array}} with names "
                        f"from {', '.join(TRAJECTORY_JOINT_NAMES)}; got "
                        f"{type(trajectories).__name__}")
    unknown = [k for k in trajectories if k not in TRAJECTORY_JOINT_NAMES]
    if unknown:
        raise ValueError(f"{name} has unknown joint names {unknown}; valid names are "
                         f"{', '.join(TRAJECTORY_JOINT_NAMES)}")
    for joint, traj in trajectories.items():
        p = _finite_array(traj, f"{name}[{joint!r}]")
        if p.ndim != 2 or p.shape[1] != dim or len(p) < 1:
            raise ValueError(f"{name}[{joint!r}] must have shape (t_r, {dim}) with t_r >= 1, "
                             f"got {p.shape}")
        if len(p) > N:
            raise ValueError(f"{name}[{joint!r}] has {len(p)} frames, more than the {N} "
                             f"frames of a generated clip")
        col = TRAJECTORY_JOINT_NAMES.index(joint)
        frames = np.arange(len(p)) if keypose_at == "first" else np.arange(N - len(p), N)
        trajectory[frames, col] = p
        mask[frames, col] = True
    return trajectory, mask


def build_condition(keypose_3d=None, keypose_at="first", trajectories_3d=None,
                    n_frames=N_FRAMES):
    """Dense keypose / trajectory condition of one clip, laid out like
    :func:`~physlab.motion.dataset.condition_from_window` (Sketch2Anim Sec. 3).

    Parameters
    ----------
    keypose_3d : None or (22, 3) float array, metres (canonical window frame).
    keypose_at : ``"first"`` (keypose at frame 0, trajectories over the first ``t_r``
        frames) or ``"last"`` (frame ``n_frames - 1``, the last ``t_r`` frames).
    trajectories_3d : None or dict ``{joint_name: (t_r, 3) array}``, names from
        :data:`~physlab.motion.dataset.TRAJECTORY_JOINT_NAMES`, ``1 <= t_r <= n_frames``
        (each joint may have its own ``t_r``).

    Returns
    -------
    dict: ``trajectory`` (N, 6, 3) float64 (zeros where masked), ``traj_mask`` (N, 6) bool,
    ``keypose`` (22, 3) float64 (zeros when absent), ``key_frame`` int, ``has_keypose`` bool,
    ``has_trajectory`` bool.
    """
    if keypose_at not in KEYPOSE_AT:
        raise ValueError(f"keypose_at must be 'first' or 'last', got {keypose_at!r}")
    N = int(n_frames)
    key_frame = 0 if keypose_at == "first" else N - 1
    keypose = np.zeros((len(JOINT_NAMES), 3))
    if keypose_3d is not None:
        keypose = _finite_array(keypose_3d, "keypose_3d", (len(JOINT_NAMES), 3))
    trajectory, mask = check_trajectories(trajectories_3d, "trajectories_3d", 3, N, keypose_at)
    return {"trajectory": trajectory, "traj_mask": mask, "keypose": keypose,
            "key_frame": key_frame, "has_keypose": keypose_3d is not None,
            "has_trajectory": bool(mask.any())}


def build_sketch(keypose_2d=None, keypose_at="first", trajectories_2d=None, camera=None,
                 n_frames=N_FRAMES):
    """Validate 2D (sketch) conditions and lay them out for the 2D guidance
    (:func:`~physlab.motion.guidance.sketch_losses`): the keypose and trajectories drawn in the
    view of ``camera`` (normalised image units, :mod:`~physlab.motion.camera`), placed as the
    3D ones are (:func:`build_condition`).

    Returns
    -------
    dict: ``trajectory`` (N, 6, 2), ``traj_mask`` (N, 6) bool, ``keypose`` (22, 2) or None,
    ``key_frame`` int, ``projection`` (2, 3) ``s · R[:2]`` or None, ``has_keypose``,
    ``has_trajectory`` bool.
    """
    from .camera import Camera

    if keypose_at not in KEYPOSE_AT:
        raise ValueError(f"keypose_at must be 'first' or 'last', got {keypose_at!r}")
    N = int(n_frames)
    key_frame = 0 if keypose_at == "first" else N - 1
    keypose = None
    if keypose_2d is not None:
        keypose = _finite_array(keypose_2d, "keypose_2d", (len(JOINT_NAMES), 2))
    trajectory, mask = check_trajectories(trajectories_2d, "trajectories_2d", 2, N, keypose_at)
    drawn = keypose is not None or bool(mask.any())
    if drawn and not isinstance(camera, Camera):
        raise ValueError(f"keypose_2d / trajectories_2d need the camera they were drawn in: "
                         f"camera=physlab.motion.camera.Camera(scale, pitch, yaw, roll), got "
                         f"{camera!r}")
    projection = camera.projection_matrix if drawn else None
    return {"trajectory": trajectory, "traj_mask": mask, "keypose": keypose,
            "key_frame": key_frame, "projection": projection,
            "has_keypose": keypose is not None, "has_trajectory": bool(mask.any())}


# ----------------------------------------------------------------------------- text guidance

#: Largest classifier-free guidance scale accepted (the paper uses 7.5).
MAX_GUIDANCE = 100.0
#: A text guidance scale given as a pair ``(w_high, w_low)`` (:func:`check_guidance`) applies
#: ``w_high`` at the noise levels ``t >= GUIDANCE_SPLIT * T`` and ``w_low`` below: a guidance
#: interval in the spirit of Kynkäänniemi et al. (2024, "Applying guidance in a limited
#: interval improves sample and distribution quality in diffusion models"). Measured on a
#: text base with a 6x finer pelvis path scale (``evaluate --adherence``, 64-128 clips per
#: text; docs/motion_experiments.md): a run's speed is settled in the upper half (w_high 6 /
#: 7 with w_low 4: runs −25 / −21 % of the real speed), a near-still action's pelvis sway in
#: the lower half (the wave +30 % at a single w = 5, +8 % at (6, 4)); moving the split to 0.3
#: or 0.7 of T changed the speeds by at most 2 points. The shipped text model samples with
#: (6, 4.5) (``Generator.text_guidance``).
GUIDANCE_SPLIT = 0.5


def check_guidance(value, name="guidance_scale"):
    """A text guidance scale checked: a number in [0, :data:`MAX_GUIDANCE`] (returned as a
    float) or a pair ``(w_high, w_low)`` of such numbers (returned as a tuple of two floats;
    :data:`GUIDANCE_SPLIT`); else a ValueError naming ``name``."""
    def ok(v):
        return (not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer,
                                                                       np.floating))
                and math.isfinite(v) and 0 <= v <= MAX_GUIDANCE)

    if ok(value):
        return float(value)
    if isinstance(value, (tuple, list)) and len(value) == 2 and all(ok(v) for v in value):
        return (float(value[0]), float(value[1]))
    raise ValueError(f"{name} must be a number in [0, {MAX_GUIDANCE:g}] (Sketch2Anim uses 7.5; "
                     f"0 = no text guidance; far larger scales overflow the features) or a "
                     f"pair (w_high, w_low) of such numbers (w_high at noise levels t >= "
                     f"{GUIDANCE_SPLIT:g} T, w_low below), got {value!r}")


def guidance_at(w, t, num_train_timesteps):
    """The text guidance scale of the step at noise level ``t``: ``w`` itself, or for a pair
    (:func:`check_guidance`) ``w_high`` if ``t >= GUIDANCE_SPLIT * T`` else ``w_low``."""
    if isinstance(w, tuple):
        return w[0] if t >= GUIDANCE_SPLIT * num_train_timesteps else w[1]
    return w


def format_guidance(w):
    """``w`` as text: ``"2.5"``, or ``"7 (t ≥ 0.5 T) / 4 (below)"`` for a pair."""
    if isinstance(w, (tuple, list)):
        return f"{w[0]:g} (t ≥ {GUIDANCE_SPLIT:g} T) / {w[1]:g} (below)"
    return f"{w:g}"


def guidance_argument(text):
    """argparse type of a ``--guidance`` option: ``W`` or ``HIGH,LOW``
    (:func:`check_guidance`)."""
    import argparse

    try:
        parts = [float(v) for v in str(text).split(",")]
        return check_guidance(parts[0] if len(parts) == 1 else parts, "--guidance")
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"{e}; write W or HIGH,LOW, e.g. 2.5 or 7,4") from None
