"""Non-learned transition baselines: fill the gap between two 22-joint motion clips.

A *transition* is the ``n`` frames strictly between the last frame of a clip ``before``
``(Tb, 22, 3)`` and the first frame of a clip ``after`` ``(Ta, 22, 3)`` (metres, y up, 20 fps,
HumanML3D joint order :data:`~physlab.motion.skeleton.JOINT_NAMES`). Frame ``k = 1..n`` of the
gap sits at the gap parameter ``h = k / (n + 1)``: ``h = 0`` is ``before[-1]``, ``h = 1`` is
``after[0]``. Sketch2Anim (supp. D, Table A4) compares its diffusion blend of storyboard
clips with these baselines:

* :func:`linear_transition` — joint *positions* interpolated linearly (also the
  initialisation of the diffusion blend). Cheap, but limbs cut chords (bones shrink) and the
  velocity jumps at both junctions.
* :func:`slerp_transition` — local joint *rotations* interpolated along the geodesic (slerp),
  the root position linearly; bone lengths stay fixed, the velocity still jumps.
* :func:`squad_transition` — local rotations by SQUAD [Shoemake 1987], the root position by a
  cubic Hermite curve with the context's end velocities; rigid. With Shoemake's own inner
  points (the default, ``tangents="shoemake"``) the rotations slow down at the junctions;
  with ``tangents="context"`` they keep the context's angular velocity (C1), which flips
  on fast, jittery generated joints (see :func:`squad_transition`).

Rotations come from joint positions through :mod:`physlab.motion.export`: one set of rest
offsets (:func:`~physlab.motion.export.rest_offsets` of the key frames, so every output frame
has the same bone lengths) and :func:`~physlab.motion.export.joint_rotations`, i.e. Kabsch
fits at the pelvis / spine3 and twist-free swings elsewhere; forward kinematics
(:func:`~physlab.motion.skeleton.forward_kinematics`) rebuilds the positions. For a rigid
input skeleton the key frames are reproduced exactly; see ``match_ends`` for generated clips
whose bone lengths drift.

SQUAD on unevenly spaced keys
    Shoemake's inner quadrangle point ``s_i = q_i exp(-(log(q_i⁻¹q_{i+1}) +
    log(q_i⁻¹q_{i-1})) / 4)`` is the special case, for evenly spaced keys, of

        ``s_0 = q_0 exp((m_0 - log(q_0⁻¹ q_1)) / 2)``,
        ``s_1 = q_1 exp(-(m_1 + log(q_1⁻¹ q_0)) / 2)``,

    where ``m_i`` is the tangent (angular velocity in the body frame of ``q_i``, in quaternion
    log units per unit ``h``): with the Catmull–Rom tangent
    ``m_i = (log(q_i⁻¹q_{i+1}) - log(q_i⁻¹q_{i-1})) / 2`` both give Shoemake's formula, and
    ``squad(q_0, q_1, s_0, s_1, h) = slerp(slerp(q_0, q_1, h), slerp(s_0, s_1, h),
    2h(1 - h))`` has derivative ``m_0`` at ``h = 0`` and ``m_1`` at ``h = 1``. The keys of a
    gap are *not* evenly spaced (one frame, ``n + 1`` frames, one frame), so the literal
    formula (the default) does not keep the context's velocity at the junctions; with
    ``tangents="context"`` the tangents are the context's angular velocities per frame
    scaled to the gap, ``m_0 = -(n + 1) log(q_0⁻¹ q_{-1})`` and
    ``m_1 = (n + 1) log(q_1⁻¹ q_2)`` (``q_{-1}, q_0`` = last two frames of ``before``,
    ``q_1, q_2`` = first two of ``after``), exactly as for the Hermite root; a joint turning
    at constant angular velocity is then continued at that velocity.

Quaternion sign
    ``q`` and ``-q`` are the same rotation. Every logarithm here is taken of a *relative*
    quaternion after flipping it to ``w >= 0`` (the shortest arc, angle <= π), so the result
    does not depend on the sign of the keys; a joint that turns by more than 180° across the
    gap is ambiguous and is interpolated the short way.

References: Shoemake 1987, "Animating rotation with quaternion curves" (SIGGRAPH), Sec. 5
(slerp, squad); Sketch2Anim supp. D, Table A4 (SQUAD baseline for transitions).
"""
from __future__ import annotations

import operator

import numpy as np

from .export import joint_rotations, rest_offsets
from .features import _check_joints
from .skeleton import PARENTS, forward_kinematics

__all__ = ["linear_transition", "slerp_transition", "squad_transition"]


# ----------------------------------------------------------------------------- validation


def _check_gap(before, after, n, min_frames, fn):
    """Validated ``(before, after, n)``; ValueErrors name the argument and the fix."""
    for name, clip in (("before", before), ("after", after)):
        shape = np.shape(clip)
        if len(shape) == 3 and shape[0] < min_frames:
            why = (" (the end velocities are estimated from the two context frames on each "
                   "side of the gap)" if min_frames == 2 else "")
            raise ValueError(f"{fn}: {name} needs at least {min_frames} frame"
                             f"{'s' if min_frames > 1 else ''}{why}, got {shape[0]}")
    before = _check_joints(before, min_frames, name="before")
    after = _check_joints(after, min_frames, name="after")
    if isinstance(n, (bool, np.bool_)):
        raise ValueError(f"{fn}: n must be an integer >= 1 (number of gap frames), got {n!r}")
    try:
        n = operator.index(n)
    except TypeError:
        raise ValueError(f"{fn}: n must be an integer >= 1 (number of gap frames), got "
                         f"{n!r}") from None
    if n < 1:
        raise ValueError(f"{fn}: n must be >= 1 (number of frames strictly between before[-1] "
                         f"and after[0]), got {n}")
    return before, after, n


# ----------------------------------------------------------------------------- quaternions
# unit quaternions (..., 4) as (w, x, y, z); logs / tangents (..., 3) in quaternion log units
# (half the rotation vector: exp(v) = (cos|v|, sin|v| v/|v|)).


def _quat_from_matrix(R):
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat()         # (N, 4) x, y, z, w
    return np.roll(q, 1, axis=-1).reshape(R.shape[:-2] + (4,))


def _quat_to_matrix(q):
    """(..., 4) unit quaternions (w, x, y, z) -> (..., 3, 3) rotation matrices."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_quat(np.roll(q, -1, axis=-1).reshape(-1, 4)).as_matrix()
    return R.reshape(q.shape[:-1] + (3, 3))


def _qconj(q):
    """Conjugate = inverse of a unit quaternion, (..., 4)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _qmul(a, b):
    """Hamilton product ``a b`` of (..., 4) quaternions (broadcasting)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def _qlog(q):
    """Shortest-arc logarithm of unit quaternions: (..., 4) -> (..., 3), ``|log q| <= π/2``.

    ``q`` and ``-q`` give the same result: ``q`` is flipped to ``w >= 0`` first.
    """
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)                  # sin(θ/2)
    half = np.arctan2(s, q[..., :1])                                # θ/2 in [0, π/2]
    return v * np.where(s > 1e-12, half / np.where(s > 1e-12, s, 1.0), 1.0)


def _qexp(v):
    """Exponential of (..., 3) pure quaternions -> (..., 4) unit quaternions."""
    phi = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.concatenate([np.cos(phi), np.sinc(phi / np.pi) * v], axis=-1)   # sinc = sin φ/φ


def _slerp(a, b, h):
    """``slerp(a, b, h) = a exp(h log(a⁻¹ b))`` [Shoemake 1987], shortest arc.

    a, b : (..., 4) unit quaternions; h : float array broadcastable to ``a.shape[:-1]``.
    """
    return _qmul(a, _qexp(np.asarray(h, dtype=float)[..., None] * _qlog(_qmul(_qconj(a), b))))


def _squad_inner_points(q0, q1, m0, m1):
    """Inner quadrangle points ``s_0, s_1`` of the SQUAD segment ``q0 -> q1`` (module
    docstring): the curve has tangent ``m0`` at ``h = 0`` and ``m1`` at ``h = 1``.

    q0, q1 : (..., 4) unit quaternions; m0, m1 : (..., 3) tangents, body frame of ``q0`` /
    ``q1``, quaternion log units per unit ``h``. Returns two (..., 4) arrays.
    """
    s0 = _qmul(q0, _qexp((m0 - _qlog(_qmul(_qconj(q0), q1))) / 2))
    s1 = _qmul(q1, _qexp(-(m1 + _qlog(_qmul(_qconj(q1), q0))) / 2))
    return s0, s1


def _squad(q0, q1, s0, s1, h):
    """``squad = slerp(slerp(q0, q1, h), slerp(s0, s1, h), 2h(1 - h))`` [Shoemake 1987].

    q0, q1, s0, s1 : (J, 4); h : (N,) -> (N, J, 4).
    """
    h = np.asarray(h, dtype=float)[:, None]                         # (N, 1)
    return _slerp(_slerp(q0, q1, h), _slerp(s0, s1, h), 2 * h * (1 - h))


# ----------------------------------------------------------------------------- helpers


def _gap_parameter(n):
    """(n + 2,) gap parameter ``h = k / (n + 1)``, ``k = 0..n+1`` (keys included)."""
    return np.arange(n + 2) / (n + 1)


def _hermite(p0, p1, m0, m1, h):
    """Cubic Hermite curve: (..., 3) end points / tangents (per unit ``h``), h (N,) -> (N, ..., 3).

    ``p(h) = (2h³ - 3h² + 1) p0 + (h³ - 2h² + h) m0 + (-2h³ + 3h²) p1 + (h³ - h²) m1``.
    """
    h = np.asarray(h, dtype=float).reshape((-1,) + (1,) * np.ndim(p0))
    h2, h3 = h * h, h * h * h
    return ((2 * h3 - 3 * h2 + 1) * p0 + (h3 - 2 * h2 + h) * m0
            + (-2 * h3 + 3 * h2) * p1 + (h3 - h2) * m1)


def _rebuild(R, offsets, root, keys, match_ends):
    """FK of the (n + 2, 22, 3, 3) local rotations; drop the two key frames.

    ``keys`` (2, 22, 3) are ``before[-1], after[0]``; with ``match_ends`` the rigid-fit
    residual at the keys is blended linearly across the gap.
    """
    x = forward_kinematics(R, offsets, PARENTS, root)              # (n + 2, 22, 3)
    if match_ends:
        h = _gap_parameter(len(x) - 2)[:, None, None]
        e0, e1 = keys[0] - x[0], keys[1] - x[-1]                   # (22, 3) fit residuals
        x = x + (1 - h) * e0 + h * e1
    return x[1:-1]


# ----------------------------------------------------------------------------- baselines


def linear_transition(before, after, n):
    """Linear interpolation of joint positions across a gap of ``n`` frames.

    ``x_k = (1 - w_k) before[-1] + w_k after[0]`` with ``w_k = k / (n + 1)``, ``k = 1..n``:
    the initialisation of Sketch2Anim's diffusion blend and its simplest baseline
    (supp. D, Table A4). Bone lengths are not preserved (limbs cut chords).

    Parameters
    ----------
    before : (Tb, 22, 3) float array, metres, context ending at the gap (Tb >= 1).
    after : (Ta, 22, 3) float array, metres, context starting after the gap (Ta >= 1).
    n : int >= 1, number of frames strictly between ``before[-1]`` and ``after[0]``.

    Returns
    -------
    (n, 22, 3) float64 array of joint positions (metres).
    """
    before, after, n = _check_gap(before, after, n, 1, "linear_transition")
    w = _gap_parameter(n)[1:-1, None, None]                          # (n, 1, 1)
    return (1 - w) * before[-1] + w * after[0]


def slerp_transition(before, after, n, match_ends=False):
    """Geodesic (slerp) interpolation of local joint rotations, linear root, across a gap.

    Local rotations ``R_j`` of ``before[-1]`` and ``after[0]`` (one set of rest offsets,
    :func:`~physlab.motion.export.rest_offsets` of those two frames) are interpolated as
    ``slerp(q_0, q_1, h) = q_0 exp(h log(q_0⁻¹ q_1))`` [Shoemake 1987] — constant angular
    velocity along the shortest arc — and the pelvis position linearly, then forward
    kinematics. Bone lengths are constant; the velocity jumps at the junctions.

    Parameters
    ----------
    before : (Tb, 22, 3) float array, metres, context ending at the gap (Tb >= 1).
    after : (Ta, 22, 3) float array, metres, context starting after the gap (Ta >= 1).
    n : int >= 1, number of gap frames; frame ``k`` is at ``h = k / (n + 1)``.
    match_ends : bool; if True, blend the rigid-fit residual of the two key frames linearly
        across the gap (see :func:`squad_transition`).

    Returns
    -------
    (n, 22, 3) float64 array of joint positions (metres).
    """
    before, after, n = _check_gap(before, after, n, 1, "slerp_transition")
    keys = np.stack([before[-1], after[0]])                          # (2, 22, 3)
    offsets = rest_offsets(keys)
    _, R = joint_rotations(keys, offsets)                            # (2, 22, 3, 3)
    q = _quat_from_matrix(R)                                         # (2, 22, 4)
    h = _gap_parameter(n)                                            # (n + 2,)
    qh = _slerp(q[0], q[1], h[:, None])                              # (n + 2, 22, 4)
    root = (1 - h[:, None]) * keys[0, 0] + h[:, None] * keys[1, 0]   # (n + 2, 3)
    return _rebuild(_quat_to_matrix(qh), offsets, root, keys, match_ends)


#: Tangents of :func:`squad_transition`.
SQUAD_TANGENTS = ("shoemake", "context")


def squad_transition(before, after, n, match_ends=False, tangents="shoemake"):
    """SQUAD interpolation of local joint rotations and Hermite root across a gap.

    The baseline "SQUAD" of Sketch2Anim supp. D, Table A4. Keys: the last two frames of
    ``before`` (``q_{-1}, q_0`` at frames -1, 0) and the first two of ``after`` (``q_1, q_2``
    at frames n + 1, n + 2). With one set of rest offsets (``rest_offsets`` of those four
    frames, :mod:`physlab.motion.export`) their local rotations come from
    :func:`~physlab.motion.export.joint_rotations`; each joint is interpolated by

        ``squad(q_0, q_1, s_0, s_1, h) = slerp(slerp(q_0, q_1, h), slerp(s_0, s_1, h),
        2h(1 - h))``  [Shoemake 1987]

    with the inner points ``s_0, s_1`` of the module docstring. ``tangents="shoemake"``
    (default): Shoemake's own ``s_i = q_i exp(−(log(q_i⁻¹q_{i+1}) + log(q_i⁻¹q_{i−1}))/4)``
    on the four keys as if evenly spaced — robust, but the rotation slows down at the
    junctions (the context's angular velocity is not kept). ``tangents="context"``: the
    context's angular velocities ``m_0 = -(n + 1) log(q_0⁻¹ q_{-1})``,
    ``m_1 = (n + 1) log(q_1⁻¹ q_2)`` (Shoemake's ``s_i`` generalised to the uneven key
    spacing 1, n + 1, 1): C1 at the junctions and exact for a constant angular velocity,
    but a fast or jittery joint (a generated wrist: 0.3 rad/frame × 21) gets a tangent past
    π and the curve flips (measured on generated clips: a 0.4 m one-frame jump inside a
    20-frame gap, AUJ 3.5 on the Table A4 analogue against 0.27 for linear). The pelvis
    position follows the cubic Hermite curve from ``p_0 = before[-1, 0]`` to
    ``p_1 = after[0, 0]`` with tangents ``(n + 1) (before[-1, 0] - before[-2, 0])`` and
    ``(n + 1) (after[1, 0] - after[0, 0])``. Forward kinematics rebuilds the positions.

    Properties: a root moving at constant velocity is continued exactly; with
    ``tangents="context"`` so is a joint turning at constant angular velocity, and the
    velocity matches the context at both junctions (C1); bone lengths are those of the rest
    offsets in every frame. All logarithms take the
    shortest arc (``q`` and ``-q`` are the same rotation).

    Parameters
    ----------
    before : (Tb, 22, 3) float array, metres, y up, context ending at the gap (Tb >= 2).
    after : (Ta, 22, 3) float array, metres, context starting after the gap (Ta >= 2).
    n : int >= 1, number of frames strictly between ``before[-1]`` and ``after[0]``; frame
        ``k = 1..n`` is at ``h = k / (n + 1)``.
    match_ends : bool, default False. The rigid fit reproduces the key frames exactly only
        when the context is a rigid skeleton (constant bone lengths — any forward-kinematics
        output, HumanML3D ground truth). Generated clips drift; with True the per-joint fit
        residuals at ``before[-1]`` and ``after[0]`` are blended linearly across the gap so
        the transition joins the context without a jump (bone lengths then vary by that
        residual). False keeps the output exactly rigid.

    Returns
    -------
    (n, 22, 3) float64 array of joint positions (metres).
    """
    if tangents not in SQUAD_TANGENTS:
        raise ValueError(f"tangents must be one of {SQUAD_TANGENTS}, got {tangents!r}")
    before, after, n = _check_gap(before, after, n, 2, "squad_transition")
    frames = np.concatenate([before[-2:], after[:2]])                # (4, 22, 3) keys -1, 0, 1, 2
    offsets = rest_offsets(frames)
    _, R = joint_rotations(frames, offsets)                          # (4, 22, 3, 3)
    qm, q0, q1, q2 = _quat_from_matrix(R)                            # each (22, 4)
    scale = n + 1                                                    # frames per unit h
    if tangents == "context":
        m0 = -scale * _qlog(_qmul(_qconj(q0), qm))                   # (22, 3) tangent at h = 0
        m1 = scale * _qlog(_qmul(_qconj(q1), q2))                    # (22, 3) tangent at h = 1
    else:                                                            # Shoemake 1987's s_i
        l01, l10 = _qlog(_qmul(_qconj(q0), q1)), _qlog(_qmul(_qconj(q1), q0))
        m0 = (l01 - _qlog(_qmul(_qconj(q0), qm))) / 2
        m1 = (_qlog(_qmul(_qconj(q1), q2)) - l10) / 2
    s0, s1 = _squad_inner_points(q0, q1, m0, m1)
    h = _gap_parameter(n)                                            # (n + 2,)
    qh = _squad(q0, q1, s0, s1, h)                                   # (n + 2, 22, 4)
    r = frames[:, 0]                                                 # (4, 3) pelvis keys
    root = _hermite(r[1], r[2], scale * (r[1] - r[0]), scale * (r[3] - r[2]), h)   # (n + 2, 3)
    return _rebuild(_quat_to_matrix(qh), offsets, root, frames[1:3], match_ends)
