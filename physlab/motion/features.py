"""A redundant per-frame motion feature vector in the spirit of HumanML3D, and its exact inverse.

HumanML3D [Guo et al. 2022, Sec. 3 / ``motion_process.py``] describes a motion of ``T``
frames of 22 joints by ``T - 1`` feature rows (root angular velocity, root linear velocity,
root height, root-relative joint positions, joint rotations, joint velocities, foot contacts;
``D = 263``). Sketch2Anim (Sec. 3, "Feature representation") uses that representation. This
module builds the same kind of vector from joint positions only (no rotations, so no
inverse kinematics is needed) and inverts it exactly.

Conventions
-----------
Joints are ``(T, 22, 3)`` float arrays in metres, y up (:mod:`physlab.motion.skeleton`).

* **Heading** ``theta_t`` (rad) of frame ``t``: the facing direction ``f`` is
  ``up x across`` with ``across = (r_hip - l_hip) + (r_shoulder - l_shoulder)`` (HumanML3D's
  ``face_joint_indx``), projected on the ground plane; ``theta = atan2(f_x, f_z)``, so
  ``theta = 0`` faces ``+z``. No temporal smoothing (HumanML3D smooths the facing over
  ~20 frames; here the features of a window do not depend on frames outside it).
* ``R_y(a)`` rotates by ``a`` about ``+y``: ``R_y(a) @ (0, 0, 1) = (sin a, 0, cos a)``.
  "In the root (heading) frame" means multiplied by ``R_y(-theta_t)``.

Feature row ``i`` (``i = 0 .. T-2``) is built from frames ``i`` and ``i + 1``:

==================  =======  =========================================================
group               columns  value
==================  =======  =========================================================
``root_ang_vel``    0        ``wrap(theta_{i+1} - theta_i)`` (rad / frame), in (-pi, pi]
``root_lin_vel``    1:3      ``R_y(-theta_i) (p_{i+1} - p_i)``, x and z (m / frame), ``p``
                             = pelvis
``root_height``     3        pelvis height ``y_i`` (m)
``ric``             4:67     joints 1..21: ``R_y(-theta_i)(x_{i,j} - (p_x, 0, p_z))`` (m);
                             HumanML3D's "rotation-invariant coordinates": xz relative to
                             the pelvis in its heading frame, y the absolute height
``local_vel``       67:133   joints 0..21: ``R_y(-theta_i)(x_{i+1,j} - x_{i,j})`` (m / frame)
``contacts``        133:137  1.0 if in contact: left ankle, left foot, right ankle, right
                             foot (HumanML3D order ``fid_l + fid_r``), see below
==================  =======  =========================================================

``D = FEATURE_DIM = 137``; the slices are :data:`FEATURE_GROUPS`. HumanML3D's 126 rotation
columns (6D local rotations) are left out.

Foot contacts (:data:`CONTACT_JOINTS`): joint ``j`` touches the ground in row ``i`` if its
height ``y_{i,j} < CONTACT_HEIGHT[j]`` **and** its speed ``|x_{i+1,j} - x_{i,j}| * fps <
CONTACT_SPEED``. Heights: ankles 0.12 m, toes ("foot" joints) 0.05 m (the Bandai-Namco
ankles rest at 0.075–0.08 m and the toes at 0–0.005 m above the ground after
:func:`~physlab.motion.bvh.retarget_to_smpl22`); speed 0.5 m/s (= 2.5 cm/frame at 20 fps,
the skating threshold of Karunratanakul et al. 2023, so a contact foot is one that does not
skate). HumanML3D uses a velocity test only (squared displacement < 0.002 m^2 per frame, i.e.
< 4.5 cm/frame; its height factors 3.0 / 2.0 m never bind).

Inverse (:func:`features_to_joints`): ``theta_0`` and the pelvis xz of frame 0 are not in the
features; the inverse takes them as arguments, by default ``theta_0 = 0`` and pelvis at
``x = z = 0`` — the pose of :func:`canonicalize`. Then ``theta_{i+1} = theta_i +
root_ang_vel_i`` (cumulative sum), ``p_{i+1} = p_i + R_y(theta_i) root_lin_vel_i``, and frame
``i`` is ``R_y(theta_i) ric_i + (p_x, 0, p_z)`` for ``i = 0 .. T-2`` (pelvis ``(p_x,
root_height_i, p_z)``). The last frame ``T - 1`` is ``x_{T-2} + R_y(theta_{T-2})
local_vel_{T-2}`` (``include_last=True``). For a canonical input every frame is reproduced to
floating-point precision (~1e-15 m).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from physlab._io import atomic_write

from .skeleton import FOOT_JOINTS, JOINT_NAMES

__all__ = [
    "FEATURE_DIM", "FEATURE_GROUPS", "ROOT_ANG_VEL", "ROOT_LIN_VEL", "ROOT_HEIGHT", "RIC",
    "LOCAL_VEL", "CONTACTS", "CONTACT_JOINTS", "CONTACT_HEIGHT", "CONTACT_SPEED",
    "FACE_JOINTS", "STD_FLOORS", "root_heading", "canonicalize", "foot_contacts",
    "joints_to_features", "features_to_joints", "FeatureStats",
    "ABS_PELVIS", "ABS_PATH", "ABS_BODY", "ABS_CONTACTS", "ABS_FEATURE_DIM", "ABS_FEATURE_GROUPS",
    "ABS_STD_FLOORS", "REPRESENTATIONS", "check_representation",
    "joints_to_absolute_features", "absolute_features_to_joints", "encode_motion",
    "decode_motion",
]

N_JOINTS = len(JOINT_NAMES)

#: Feature layout: column slices of each group in a feature row (see the module docstring).
ROOT_ANG_VEL = slice(0, 1)
ROOT_LIN_VEL = slice(1, 3)
ROOT_HEIGHT = slice(3, 4)
RIC = slice(4, 4 + 3 * (N_JOINTS - 1))                       # 4:67
LOCAL_VEL = slice(RIC.stop, RIC.stop + 3 * N_JOINTS)          # 67:133
CONTACTS = slice(LOCAL_VEL.stop, LOCAL_VEL.stop + 4)          # 133:137
FEATURE_DIM = CONTACTS.stop                                   # 137
FEATURE_GROUPS = {
    "root_ang_vel": ROOT_ANG_VEL, "root_lin_vel": ROOT_LIN_VEL, "root_height": ROOT_HEIGHT,
    "ric": RIC, "local_vel": LOCAL_VEL, "contacts": CONTACTS,
}

#: Right hip, left hip, right shoulder, left shoulder (HumanML3D ``face_joint_indx``).
FACE_JOINTS = (2, 1, 17, 16)
#: Left ankle, left foot, right ankle, right foot (HumanML3D ``fid_l + fid_r``).
CONTACT_JOINTS = (7, 10, 8, 11)
#: Height below which each :data:`CONTACT_JOINTS` joint may be in contact (m).
CONTACT_HEIGHT = (0.12, 0.05, 0.12, 0.05)
#: Speed below which a low joint is in contact (m/s); 2.5 cm/frame at 20 fps.
CONTACT_SPEED = 0.5

#: Lower bounds of the per-dimension std in :class:`FeatureStats`, per group, in the group's
#: units (rad/frame, m/frame, m, m, m/frame, contact). Measured on all 2524 Bandai-Namco
#: 40-frame windows the stds are: root_ang_vel 0.044, root_lin_vel >= 0.011, root_height
#: 0.034, ric >= 0.0018 (median 0.05), local_vel >= 0.011, contacts >= 0.44; so the floors
#: bind only for (near-)constant columns: the hips' lateral offsets in the heading frame
#: (std 0.002 m, the hips define the heading) and columns of small training subsets.
STD_FLOORS = {"root_ang_vel": 1e-3, "root_lin_vel": 1e-3, "root_height": 5e-3, "ric": 5e-3,
              "local_vel": 1e-3, "contacts": 0.1}


def _check_joints(joints, min_frames=1, name="joints"):
    x = np.asarray(joints, dtype=float)
    if x.ndim != 3 or x.shape[1:] != (N_JOINTS, 3):
        raise ValueError(f"{name} must have shape (T, {N_JOINTS}, 3) (frames, joints, xyz in "
                         f"metres), got {x.shape}")
    if x.shape[0] < min_frames:
        raise ValueError(f"{name} needs at least {min_frames} frames, got {x.shape[0]}")
    if not np.all(np.isfinite(x)):
        bad = np.argwhere(~np.isfinite(x))[0]
        raise ValueError(f"{name} contains NaN or inf (first at frame {bad[0]}, joint "
                         f"{JOINT_NAMES[bad[1]]}); clean or drop those frames first")
    return x


def _rotate_y(v, angle):
    """``R_y(angle) v`` for v ``(T, ..., 3)`` and angle ``(T,)`` (rad); returns a new array."""
    a = np.asarray(angle, dtype=float).reshape((-1,) + (1,) * (v.ndim - 2))
    c, s = np.cos(a), np.sin(a)
    out = np.array(v, dtype=float)
    out[..., 0] = c * v[..., 0] + s * v[..., 2]
    out[..., 2] = -s * v[..., 0] + c * v[..., 2]
    return out


def root_heading(joints):
    """Heading angle of every frame: ``theta = atan2(f_x, f_z)`` of the facing direction.

    ``f = up x across``, ``across = (r_hip - l_hip) + (r_shoulder - l_shoulder)``
    (HumanML3D ``process_file``), so a person facing ``+z`` has ``theta = 0``.

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up.

    Returns
    -------
    (T,) float array of angles in (-pi, pi] (rad). ValueError if the hips and shoulders are
    (nearly) vertical-aligned so that no horizontal facing direction exists.
    """
    x = _check_joints(joints)
    r_hip, l_hip, r_sh, l_sh = FACE_JOINTS
    across = x[:, r_hip] - x[:, l_hip] + x[:, r_sh] - x[:, l_sh]           # (T, 3)
    # f = (0, 1, 0) x across = (across_z, 0, -across_x)
    fx, fz = across[:, 2], -across[:, 0]
    norm = np.hypot(fx, fz)
    if np.any(norm < 1e-6):
        raise ValueError(f"no horizontal facing direction in frames "
                         f"{np.flatnonzero(norm < 1e-6)[:5].tolist()}: the hips and shoulders "
                         f"are aligned with the vertical")
    return np.arctan2(fx, fz)


def canonicalize(joints, ground=True, return_transform=False):
    """Move a motion so that its first frame has the pelvis at ``x = z = 0``, facing ``+z``.

    ``x' = R_y(-theta_0) (x - (p_x, 0, p_z))`` with ``theta_0`` = :func:`root_heading` of
    frame 0 and ``p`` its pelvis. With ``ground=True`` the motion is also shifted vertically
    so that the lowest ankle / foot joint over all frames is at ``y = 0``, the rule of
    :func:`~physlab.motion.bvh.retarget_to_smpl22` (which grounds whole clips but leaves the
    horizontal placement and facing as in the file). Use ``ground=False`` for windows cut
    from a grounded clip, so that a window in the air (a jump) stays in the air.

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up.
    ground : bool, also put the lowest foot joint on ``y = 0``.
    return_transform : bool, also return ``(theta_0, offset)``.

    Returns
    -------
    (T, 22, 3) float array; with ``return_transform``, also ``theta_0`` (float, rad) and
    ``offset`` ((3,) float, m), such that ``x = R_y(theta_0) x' + offset``.
    """
    x = _check_joints(joints)
    theta0 = float(root_heading(x[:1])[0])
    offset = np.array([x[0, 0, 0], 0.0, x[0, 0, 2]])
    if ground:
        offset[1] = x[:, list(FOOT_JOINTS), 1].min()
    out = _rotate_y(x - offset, np.full(len(x), -theta0))
    if return_transform:
        return out, theta0, offset
    return out


def foot_contacts(joints, fps=20.0, height=CONTACT_HEIGHT, speed=CONTACT_SPEED):
    """Foot contact labels of :data:`CONTACT_JOINTS` for frames ``0 .. T-2``.

    Joint ``j`` is in contact in frame ``i`` if ``y_{i,j} < height[j]`` and
    ``|x_{i+1,j} - x_{i,j}| * fps < speed`` (module docstring).

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up, ground at ``y = 0``; ``T >= 2``.
    fps : float > 0, frame rate (Hz).
    height : 4 floats (m), thresholds for left ankle, left foot, right ankle, right foot.
    speed : float (m/s).

    Returns
    -------
    (T-1, 4) float array of 0.0 / 1.0.
    """
    x = _check_joints(joints, min_frames=2)
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    height = np.asarray(height, dtype=float)
    if height.shape != (len(CONTACT_JOINTS),):
        raise ValueError(f"height must give 4 thresholds (left ankle, left foot, right ankle, "
                         f"right foot), got shape {height.shape}")
    feet = x[:, list(CONTACT_JOINTS)]                                      # (T, 4, 3)
    v = np.linalg.norm(feet[1:] - feet[:-1], axis=-1) * fps                # (T-1, 4) m/s
    return ((feet[:-1, :, 1] < height) & (v < speed)).astype(float)


def joints_to_features(joints, fps=20.0):
    """HumanML3D-style features of a motion: ``(T, 22, 3)`` joints -> ``(T-1, 137)``.

    Row ``i`` describes frame ``i`` and its step to frame ``i + 1``; layout in the module
    docstring and :data:`FEATURE_GROUPS`. Invariant to a rotation about ``y`` and a
    horizontal translation of the whole motion (only the contacts use absolute heights).

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up, ground at ``y = 0``; ``T >= 2``.
    fps : float > 0, frame rate (Hz), used by the contact speed threshold only (velocities
        are per frame, as in HumanML3D).

    Returns
    -------
    (T-1, FEATURE_DIM) float array.
    """
    x = _check_joints(joints, min_frames=2)
    T = len(x)
    theta = root_heading(x)                                                # (T,)
    root = x[:, 0]                                                         # (T, 3)
    f = np.empty((T - 1, FEATURE_DIM))
    f[:, 0] = np.angle(np.exp(1j * (theta[1:] - theta[:-1])))              # wrap to (-pi, pi]
    f[:, ROOT_LIN_VEL] = _rotate_y(root[1:] - root[:-1], -theta[:-1])[:, [0, 2]]
    f[:, 3] = root[:-1, 1]
    rel = x[:-1, 1:] - root[:-1, None] * np.array([1.0, 0.0, 1.0])         # (T-1, 21, 3)
    f[:, RIC] = _rotate_y(rel, -theta[:-1]).reshape(T - 1, -1)
    f[:, LOCAL_VEL] = _rotate_y(x[1:] - x[:-1], -theta[:-1]).reshape(T - 1, -1)
    f[:, CONTACTS] = foot_contacts(x, fps=fps)
    return f


def features_to_joints(features, include_last=True, initial_heading=0.0,
                       initial_root_xz=(0.0, 0.0)):
    """Joint positions from :func:`joints_to_features` output (its exact inverse).

    The heading and pelvis are integrated from the root velocities, starting from
    ``initial_heading`` and ``initial_root_xz`` (default: the canonical pose of
    :func:`canonicalize`, pelvis at the origin facing ``+z``); frames ``0 .. T-2`` come from
    the root-relative positions and frame ``T-1`` from frame ``T-2`` plus the last joint
    velocities (module docstring). Contacts are not used.

    Parameters
    ----------
    features : (T-1, FEATURE_DIM) float array (denormalised).
    include_last : bool, also return frame ``T-1`` (default), so that
        ``features_to_joints(joints_to_features(x))`` has the shape of ``x``.
    initial_heading : float, ``theta_0`` (rad).
    initial_root_xz : 2 floats, pelvis ``(x, z)`` of frame 0 (m).

    Returns
    -------
    (T, 22, 3) float array (``(T-1, 22, 3)`` without the last frame), metres.
    """
    f = np.asarray(features, dtype=float)
    if f.ndim != 2 or f.shape[1] != FEATURE_DIM:
        raise ValueError(f"features must have shape (T-1, {FEATURE_DIM}), got {f.shape}")
    if len(f) == 0:
        raise ValueError("features has no rows; a motion of T frames has T-1 rows")
    if not np.all(np.isfinite(f)):
        raise ValueError(f"features contains NaN or inf in rows "
                         f"{np.flatnonzero(~np.isfinite(f).all(axis=1))[:5].tolist()}")
    n = len(f)
    theta = initial_heading + np.concatenate([[0.0], np.cumsum(f[:-1, 0])])      # (n,)
    step = np.zeros((n, 3))
    step[:, [0, 2]] = f[:, ROOT_LIN_VEL]
    step = _rotate_y(step, theta)                                           # world root steps
    root = np.zeros((n, 3))
    root[:, [0, 2]] = np.asarray(initial_root_xz, dtype=float)
    root[1:] += np.cumsum(step[:-1], axis=0)
    x = np.empty((n + 1 if include_last else n, N_JOINTS, 3))
    x[:n, 1:] = _rotate_y(f[:, RIC].reshape(n, N_JOINTS - 1, 3), theta)
    x[:n, 1:, 0] += root[:, None, 0]
    x[:n, 1:, 2] += root[:, None, 2]
    x[:n, 0] = root
    x[:n, 0, 1] = f[:, 3]
    if include_last:
        x[n] = x[n - 1] + _rotate_y(f[-1:, LOCAL_VEL].reshape(1, N_JOINTS, 3), theta[-1:])[0]
    return x


# ----------------------------------------------------------------------------- absolute


#: Layout of the ``"absolute"`` representation (one row per frame): pelvis position in the
#: canonical (window) frame, the other 21 joints relative to the pelvis (world axes, no
#: heading rotation) and the four foot contacts. Decoding is a sum, so a trajectory or
#: keypose condition at frame ``i`` is a function of row ``i`` alone.
ABS_PELVIS = slice(0, 3)
#: The pelvis x and z columns (its path on the floor), without the height.
ABS_PATH = (ABS_PELVIS.start, ABS_PELVIS.start + 2)
ABS_BODY = slice(3, 3 + 3 * (N_JOINTS - 1))                   # 3:66
ABS_CONTACTS = slice(ABS_BODY.stop, ABS_BODY.stop + 4)        # 66:70
ABS_FEATURE_DIM = ABS_CONTACTS.stop                           # 70
ABS_FEATURE_GROUPS = {"pelvis": ABS_PELVIS, "body": ABS_BODY, "contacts": ABS_CONTACTS}
#: Std floors of the absolute groups (m, m, contact); the data stds are >= 0.03 m.
ABS_STD_FLOORS = {"pelvis": 5e-3, "body": 5e-3, "contacts": 0.1}

#: Feature representations the generator can denoise: name -> (columns, rows of a motion of
#: ``T`` frames minus ``T``). ``"relative"``: HumanML3D-style rows (module docstring), ``T - 1``
#: rows; ``"absolute"``: :func:`joints_to_absolute_features`, ``T`` rows.
REPRESENTATIONS = {"relative": (FEATURE_DIM, -1), "absolute": (ABS_FEATURE_DIM, 0)}


def check_representation(representation):
    """The name if it is a key of :data:`REPRESENTATIONS`, else ValueError."""
    if representation not in REPRESENTATIONS:
        raise ValueError(f"representation must be one of {sorted(REPRESENTATIONS)}, got "
                         f"{representation!r}")
    return representation


def joints_to_absolute_features(joints, fps=20.0):
    """The ``"absolute"`` features of a motion: ``(T, 22, 3)`` joints -> ``(T, 70)``.

    Row ``i``: pelvis ``p_i`` (3, m), joints ``x_{i,j} - p_i`` for ``j = 1..21`` (63, m) and
    the foot contacts of frame ``i`` (4; the last frame repeats those of frame ``T-2``).
    Unlike :func:`joints_to_features` this is not invariant to the placement of the motion:
    call it on canonical windows (:func:`canonicalize`), whose first pelvis is at
    ``x = z = 0`` facing ``+z``. Its inverse, :func:`absolute_features_to_joints`, is a sum,
    so a joint's position at frame ``i`` depends on row ``i`` only: the controlled generator
    does not have to integrate velocities to place a trajectory (see
    :mod:`physlab.motion.train`).

    Parameters
    ----------
    joints : (T, 22, 3) float array, metres, y up; ``T >= 2``.
    fps : float > 0, frame rate (contacts only).

    Returns
    -------
    (T, ABS_FEATURE_DIM) float array.
    """
    x = _check_joints(joints, min_frames=2)
    T = len(x)
    f = np.empty((T, ABS_FEATURE_DIM))
    f[:, ABS_PELVIS] = x[:, 0]
    f[:, ABS_BODY] = (x[:, 1:] - x[:, :1]).reshape(T, -1)
    c = foot_contacts(x, fps=fps)                                          # (T-1, 4)
    f[:, ABS_CONTACTS] = np.concatenate([c, c[-1:]])
    return f


def absolute_features_to_joints(features):
    """Joints ``(T, 22, 3)`` from ``"absolute"`` features ``(T, 70)`` (the exact inverse of
    :func:`joints_to_absolute_features`; contacts are not used)."""
    f = np.asarray(features, dtype=float)
    if f.ndim != 2 or f.shape[1] != ABS_FEATURE_DIM or len(f) == 0:
        raise ValueError(f"features must have shape (T, {ABS_FEATURE_DIM}) with T >= 1, got "
                         f"{f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError(f"features contains NaN or inf in rows "
                         f"{np.flatnonzero(~np.isfinite(f).all(axis=1))[:5].tolist()}")
    p = f[:, None, ABS_PELVIS]                                             # (T, 1, 3)
    return np.concatenate([p, p + f[:, ABS_BODY].reshape(len(f), N_JOINTS - 1, 3)], axis=1)


def encode_motion(joints, representation="relative", fps=20.0):
    """Features of ``joints`` (T, 22, 3) in the named representation (:data:`REPRESENTATIONS`):
    :func:`joints_to_features` or :func:`joints_to_absolute_features`."""
    if check_representation(representation) == "absolute":
        return joints_to_absolute_features(joints, fps=fps)
    return joints_to_features(joints, fps=fps)


def decode_motion(features, representation="relative"):
    """Joints ``(T, 22, 3)`` of (denormalised) features in the named representation: the
    inverse of :func:`encode_motion` (a relative motion starts canonically)."""
    if check_representation(representation) == "absolute":
        return absolute_features_to_joints(features)
    return features_to_joints(features)


def _group_of_columns(groups=None):
    """Array of group names, one per column of the layout ``groups`` (name -> slice;
    default :data:`FEATURE_GROUPS`)."""
    groups = FEATURE_GROUPS if groups is None else groups
    names = np.empty(max(s.stop for s in groups.values()), dtype=object)
    for g, s in groups.items():
        names[s] = g
    return names


@dataclass(eq=False)
class FeatureStats:
    """Per-dimension mean and std of feature rows, for ``(f - mean) / std`` normalisation.

    Attributes
    ----------
    mean : (D,) float array.
    std : (D,) float array, > 0: the data std of each column, raised to the floor of its
        group (:data:`STD_FLOORS`) so that constant columns do not blow up.
    """

    mean: np.ndarray
    std: np.ndarray

    def __post_init__(self):
        self.mean = np.asarray(self.mean, dtype=float).reshape(-1)
        self.std = np.asarray(self.std, dtype=float).reshape(-1)
        if self.mean.shape != self.std.shape:
            raise ValueError(f"mean {self.mean.shape} and std {self.std.shape} must have the "
                             f"same shape")
        if not (np.all(np.isfinite(self.mean)) and np.all(self.std > 0)):
            raise ValueError("mean must be finite and std > 0 in every dimension")

    @classmethod
    def from_features(cls, features, floors=None, representation="relative"):
        """Statistics of a data set of feature rows.

        Parameters
        ----------
        features : (..., D) float array (e.g. ``(N, T-1, D)`` windows), or a list of
            ``(T_k, D)`` arrays, with ``D`` the representation's width (``FEATURE_DIM`` or
            ``ABS_FEATURE_DIM``).
        floors : None or dict group name -> minimum std; None takes :data:`STD_FLOORS`
            (:data:`ABS_STD_FLOORS` for ``"absolute"``; missing groups also take it).
        representation : a key of :data:`REPRESENTATIONS`.

        Returns
        -------
        :class:`FeatureStats`.
        """
        absolute = check_representation(representation) == "absolute"
        D = ABS_FEATURE_DIM if absolute else FEATURE_DIM
        groups = ABS_FEATURE_GROUPS if absolute else FEATURE_GROUPS
        if isinstance(features, (list, tuple)):
            rows = np.concatenate([np.asarray(a, dtype=float).reshape(-1, D)
                                   for a in features]) if features else np.zeros((0, 0))
        else:
            rows = np.asarray(features, dtype=float)
            if rows.ndim < 1 or rows.shape[-1] != D:
                raise ValueError(f"features must have shape (..., {D}), got {rows.shape}")
            rows = rows.reshape(-1, D)
        if rows.shape[0] < 2:
            raise ValueError(f"need at least 2 feature rows for statistics, got {rows.shape[0]}")
        if not np.all(np.isfinite(rows)):
            raise ValueError("features contains NaN or inf")
        floors = dict(ABS_STD_FLOORS if absolute else STD_FLOORS, **(floors or {}))
        unknown = sorted(set(floors) - set(groups))
        if unknown:
            raise ValueError(f"unknown feature groups {unknown}; expected "
                             f"{', '.join(groups)}")
        floor = np.array([floors[g] for g in _group_of_columns(groups)], dtype=float)
        return cls(mean=rows.mean(axis=0), std=np.maximum(rows.std(axis=0), floor))

    def _check(self, f):
        f = np.asarray(f, dtype=float)
        if f.shape[-1:] != self.mean.shape:
            raise ValueError(f"features must have shape (..., {self.mean.shape[0]}), got "
                             f"{f.shape}")
        return f

    def normalize(self, features):
        """``(f - mean) / std`` for ``(..., D)`` features."""
        return (self._check(features) - self.mean) / self.std

    def denormalize(self, features):
        """``f * std + mean`` for ``(..., D)`` normalised features."""
        return self._check(features) * self.std + self.mean

    def save(self, path):
        """Write ``mean`` and ``std`` to an ``.npz`` file (atomically); returns the path."""
        return atomic_write(path, lambda tmp: np.savez(tmp, mean=self.mean, std=self.std),
                            suffix=".npz")

    @classmethod
    def load(cls, path):
        """Read statistics written by :meth:`save`."""
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"no feature statistics at {path}; compute them with "
                                    f"FeatureStats.from_features(...) and save() first")
        with np.load(path) as z:
            if "mean" not in z or "std" not in z:
                raise ValueError(f"{path} has no 'mean' / 'std' arrays; not a FeatureStats file")
            return cls(mean=z["mean"], std=z["std"])
