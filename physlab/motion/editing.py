"""Editing a generated motion in 3D (Sketch2Anim Sec. 7.4, Figs. 11 and 13).

Sketch2Anim's generator takes 3D keyposes and trajectories as well as drawn ones, so a clip
it made can be edited by its own conditions: read the keypose and trajectories off the clip
(:func:`extract_conditions`), move a few trajectory sample points or a keypose joint
(:func:`drag_trajectory`, :func:`move_joint`), and generate again with the edited 3D
conditions (:func:`regenerate`). Because the network re-plans the whole body around the new
points (and the guidance pulls them in), the edited clip follows the points and stays a
motion of the action, rather than a warped copy of the old one.

All joints arrays are ``(T, 22, 3)`` metres, y up, in the clip's canonical frame (the frame
:func:`~physlab.motion.generate` returns, first pelvis at the origin facing ``+z``).
"""
from __future__ import annotations

import numpy as np

from .conditions import KEYPOSE_AT, N_FRAMES
from .dataset import TRAJECTORY_JOINT_NAMES
from .features import canonicalize
from .skeleton import JOINT_NAMES, joint_index

__all__ = ["extract_conditions", "drag_trajectory", "move_joint", "regenerate",
           "reverse_trajectory", "impact_of_conditions", "DRAG_RADIUS"]

#: Samples on each side of a dragged trajectory point that follow it (Gaussian falloff).
DRAG_RADIUS = 6


def _joints(joints, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim != 3 or x.shape[1:] != (len(JOINT_NAMES), 3):
        raise ValueError(f"{name} must be a (T, {len(JOINT_NAMES)}, 3) joints array (m), got "
                         f"shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} contains NaN or inf")
    return x


def extract_conditions(joints, keypose_at="first", trajectory_joints=("pelvis",), frames=None):
    """The 3D conditions that describe a clip: its keypose at the first or last frame and the
    paths of ``trajectory_joints`` over ``frames`` frames from that end.

    joints : (40, 22, 3) m, canonical frame; keypose_at : ``"first"`` | ``"last"``;
    trajectory_joints : names from :data:`~physlab.motion.dataset.TRAJECTORY_JOINT_NAMES`;
    frames : None (all 40) or ``1 <= t_r <= 40``.

    Returns dict ``keypose_3d`` (22, 3), ``trajectories_3d`` ``{name: (t_r, 3)}``,
    ``keypose_at`` — keywords of :func:`~physlab.motion.generate`.
    """
    x = _joints(joints)
    if isinstance(trajectory_joints, str):
        raise ValueError(f"trajectory_joints must be a sequence of joint names such as "
                         f"('pelvis',), got the string {trajectory_joints!r}")
    if frames is not None and (isinstance(frames, bool)
                               or not isinstance(frames, (int, np.integer))):
        raise ValueError(f"frames must be None or an integer in 1..{N_FRAMES}, got {frames!r}")
    if len(x) != N_FRAMES:
        raise ValueError(f"joints must be a {N_FRAMES}-frame clip, got {len(x)} frames")
    if keypose_at not in KEYPOSE_AT:
        raise ValueError(f"keypose_at must be 'first' or 'last', got {keypose_at!r}")
    t_r = N_FRAMES if frames is None else int(frames)
    if not 1 <= t_r <= N_FRAMES:
        raise ValueError(f"frames must be in 1..{N_FRAMES}, got {frames!r}")
    bad = [n for n in trajectory_joints if n not in TRAJECTORY_JOINT_NAMES]
    if bad:
        raise ValueError(f"trajectory_joints has unknown names {bad}; valid names are "
                         f"{', '.join(TRAJECTORY_JOINT_NAMES)}")
    span = slice(0, t_r) if keypose_at == "first" else slice(N_FRAMES - t_r, N_FRAMES)
    key = x[0] if keypose_at == "first" else x[-1]
    return {"keypose_3d": key.copy(), "keypose_at": keypose_at,
            "trajectories_3d": {n: x[span, joint_index(n)].copy() for n in trajectory_joints}}


def _trajectory(trajectory, name="trajectory"):
    p = np.asarray(trajectory, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 1:
        raise ValueError(f"{name} must be a (t_r, 3) array of positions (m), got shape "
                         f"{p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{name} contains NaN or inf")
    return p


def _point(point, name="point"):
    q = np.asarray(point, dtype=float)
    if q.shape != (3,) or not np.all(np.isfinite(q)):
        raise ValueError(f"{name} must be a finite (3,) position in metres, got {point!r}")
    return q


def drag_trajectory(trajectory, index, point, radius=DRAG_RADIUS):
    """Move sample ``index`` of a trajectory to ``point`` and its neighbours along with it,
    by ``exp(−(k − index)² / (2 (radius/2)²))`` of the displacement (so a drag bends the path
    smoothly instead of kinking it); ``radius = 0`` moves the one sample.

    trajectory : (t_r, 3) m; index : int; point : (3,) m. Returns a new (t_r, 3) array.
    """
    p = _trajectory(trajectory)
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise ValueError(f"index must be an integer sample index, got {index!r}")
    if not -len(p) <= int(index) < len(p):
        raise ValueError(f"index {index} is outside the trajectory's {len(p)} samples")
    q = _point(point)
    i = int(index) % len(p)
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating)) \
            or not np.isfinite(radius) or radius < 0:
        raise ValueError(f"radius must be a finite number >= 0 samples, got {radius!r}")
    k = np.arange(len(p))
    w = (k == i).astype(float) if radius == 0 else np.exp(-(k - i) ** 2 / (2 * (radius / 2) ** 2))
    return p + w[:, None] * (q - p[i])


def move_joint(keypose, joint, point):
    """A copy of ``keypose`` (22, 3) with ``joint`` (name or index) at ``point`` (3,) m. The
    generator's guidance keeps the bones at the keypose's lengths, so move end effectors
    (wrists, feet, head) by small amounts or move a whole limb."""
    k = np.array(keypose, dtype=float)
    if k.shape != (len(JOINT_NAMES), 3):
        raise ValueError(f"keypose must be a ({len(JOINT_NAMES)}, 3) array, got {k.shape}")
    if isinstance(joint, str):
        j = joint_index(joint)
    elif isinstance(joint, (int, np.integer)) and not isinstance(joint, bool) \
            and 0 <= joint < len(JOINT_NAMES):
        j = int(joint)
    else:
        raise ValueError(f"joint must be a joint name or an index in 0..{len(JOINT_NAMES) - 1}, "
                         f"got {joint!r}")
    k[j] = _point(point)
    return k


def reverse_trajectory(trajectory):
    """The path walked the other way round, starting where it started: ``p_0 − (p_k − p_0)``
    reflected through the start (Fig. 13's "reverse the trajectory"), heights kept."""
    p = _trajectory(trajectory)
    out = 2 * p[:1] - p
    out[:, 1] = p[:, 1]
    return out


def regenerate(action, conditions, seed=0, generator=None, **options):
    """Generate again from edited 3D conditions (:func:`extract_conditions`' dict, edited):
    ``generate(action, **conditions, seed=seed, **options)`` with the shipped (or given)
    generator. Returns (40, 22, 3)."""
    from .sampling import load_generator

    gen = generator if generator is not None else load_generator()
    allowed = {"keypose_3d", "trajectories_3d", "keypose_at"}
    unknown = sorted(set(conditions) - allowed)
    if unknown:
        raise ValueError(f"conditions has unknown keys {unknown}; use {sorted(allowed)}")
    return gen(action, seed=seed, **conditions, **options)


def impact_of_conditions(action="a person walks", new_action="a person runs", seed=0,
                         generator=None, **options):
    """Fig. 13's sequence: (1) the action alone, (2) + the keypose of clip (1)'s last frame
    (moved to the origin, facing ``+z``) as the first frame (the clip starts from that pose), (3) + clip (1)'s pelvis
    path reversed, (4) the same conditions with the action word changed.

    Returns a list of ``(label, joints (40, 22, 3), conditions)``."""
    from .sampling import load_generator

    gen = generator if generator is not None else load_generator()
    first = gen(action, seed=seed, **options)
    key = canonicalize(first[-1:], ground=False)[0]         # last pose, at the origin facing +z
    c2 = {"keypose_3d": key, "keypose_at": "first"}
    second = gen(action, seed=seed, **c2, **options)
    c3 = dict(c2, trajectories_3d={"pelvis": reverse_trajectory(first[:, 0])})
    third = gen(action, seed=seed, **c3, **options)
    fourth = gen(new_action, seed=seed, **c3, **options)
    return [(f"'{action}'", first, {}), ("+ keypose", second, c2),
            ("+ reversed path", third, c3), (f"'{new_action}'", fourth, c3)]
