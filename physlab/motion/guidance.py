"""The control losses of Sketch2Anim Sec. 4.3 — trajectory ``L_tr`` (Eq. (6)) and keypose
``L_key`` (Eq. (8)) on decoded clean features — shared by training (:mod:`.train`, Eqs.
(5)–(9)) and by the inference guidance of sampling (:mod:`.sampling`, supp. C; the 2D
guidance of Eqs. (15)–(16) extends it).
"""
from __future__ import annotations

import torch

from .dataset import TRAJECTORY_JOINTS
from .model import features_to_joints_torch

__all__ = ["control_losses", "joint_control_losses", "projected_trajectory_loss",
           "sketch_losses"]


def control_losses(x0_hat, joints, cond, mean, std, representation="relative"):
    """``L_tr`` (Eq. (6)) and ``L_key`` (Eq. (8)) of predicted clean features.

    Parameters
    ----------
    x0_hat : (B, T, D) normalised x̂₀ (Eq. (7)); joints : (B, T+1, 22, 3) ground truth (m);
    cond : condition dict (:func:`condition_batch`; an optional ``keypose_mask`` (B,) bool
        leaves samples without a keypose out of L_key); mean, std : (D,) tensors.
    representation : the features' representation (``DenoiserConfig.representation``).

    Returns
    -------
    (L_tr, L_key) scalars in m²: L_tr is the masked mean over (frame, trajectory joint) of
    squared distances, L_key the squared distance of the root-relative pose at the key
    frame, summed over the 22 joints (the norm of Eq. (8) is over the whole frame).
    """
    pred = features_to_joints_torch(x0_hat * std + mean,                    # (B, N, J, 3) R(x̂₀)
                                    representation=representation)
    return joint_control_losses(pred, joints, cond)


def joint_control_losses(pred, joints, cond):
    """``(L_tr, L_key)`` of :func:`control_losses` from decoded joints ``pred`` (B, N, 22, 3)
    = ``R(x̂₀)`` (m): for a caller that has decoded x̂₀ already (the inference guidance
    decodes once per evaluation of G). ``joints`` and ``cond`` as there."""
    tj = list(TRAJECTORY_JOINTS)
    m = cond["traj_mask"].to(pred.dtype)                                     # (B, N, 6)
    d2 = ((pred[:, :, tj] - joints[:, :, tj]) ** 2).sum(-1)                  # (B, N, 6)
    l_tr = ((m * d2).sum((1, 2)) / m.sum((1, 2)).clamp(min=1)).mean()       # Eq. (6)
    b = torch.arange(pred.shape[0])
    kf = cond["key_frame"]
    rel_p = pred[b, kf] - pred[b, kf, :1]                                    # (B, J, 3) R'(x̂₀)
    rel_g = joints[b, kf] - joints[b, kf, :1]
    e_key = ((rel_p - rel_g) ** 2).sum((1, 2))                               # Eq. (8), m'_i one-hot
    km = cond.get("keypose_mask")
    if km is None:
        l_key = e_key.mean()
    else:
        km = km.to(e_key.dtype)
        l_key = (km * e_key).sum() / km.sum().clamp(min=1)
    return l_tr, l_key


def projected_trajectory_loss(x0_hat, joints, traj_mask, projection, mean, std,
                              representation="relative"):
    """The trajectory error of predicted clean features as drawn: the masked mean over
    (frame, trajectory joint) of the squared 2D distance between ``P(R(x̂₀), v_b)`` and
    ``P(x, v_b)``, the ground truth seen through each sample's camera (Eq. (16)'s ``G`` with a
    noise-free drawing; depth does not count).

    Parameters
    ----------
    x0_hat : (B, T, D) normalised x̂₀; joints : (B, T+1, 22, 3) ground truth (m);
    traj_mask : (B, T, 6) bool; projection : (B, 2, 3) ``s · R[:2]`` per sample
        (:func:`~physlab.motion.align.camera_projections`); mean, std : (D,) tensors.

    Returns
    -------
    scalar tensor in normalised image units².
    """
    pred = features_to_joints_torch(x0_hat * std + mean, representation=representation)
    tj = list(TRAJECTORY_JOINTS)
    p = projection.to(pred.dtype)[:, None, None]                            # (B, 1, 1, 2, 3)
    diff = pred[:, :, tj] - joints[:, :pred.shape[1], tj].to(pred.dtype)     # (B, T, 6, 3)
    d2 = ((p @ diff[..., None])[..., 0] ** 2).sum(-1)                        # (B, T, 6)
    m = traj_mask.to(pred.dtype)
    return ((m * d2).sum((1, 2)) / m.sum((1, 2)).clamp(min=1)).mean()


def sketch_losses(joints, sketch):
    """The 2D guidance terms of a sketch (Sketch2Anim supp. C): ``G`` of Eq. (16), the masked
    mean squared distance between the projected trajectory joints ``P(x̂₀, v)`` and the drawn
    2D trajectories, and its keypose analogue, the squared distance of the root-relative
    projected pose at the key frame to the drawn one, summed over the 22 joints (Eq. (8) in
    the picture; the paper leaves the keypose to its 2D encoders, which physlab has not
    trained yet, so the guidance carries it).

    Parameters
    ----------
    joints : (B, N, 22, 3) decoded joints R(x̂₀) (m).
    sketch : dict with ``projection`` (2, 3) tensor ``s · R[:2]`` of the camera
        (:class:`~physlab.motion.camera.Camera`), ``trajectory`` (B, N, 6, 2) and
        ``traj_mask`` (B, N, 6) bool (normalised image units, the :data:`TRAJECTORY_JOINTS`),
        ``keypose`` None or (B, 22, 2), ``key_frame`` int.

    Returns
    -------
    (G, L_key2D) scalars in normalised units².
    """
    p = joints @ sketch["projection"].to(joints.dtype).T                    # (B, N, 22, 2)
    g = joints.new_zeros(())
    m = sketch["traj_mask"].to(p.dtype)
    if bool(m.any()):
        d2 = ((p[:, :, list(TRAJECTORY_JOINTS)] - sketch["trajectory"].to(p.dtype)) ** 2).sum(-1)
        g = (m * d2).sum() / m.sum().clamp(min=1)                            # Eq. (16)
    key = sketch.get("keypose")
    l_key = joints.new_zeros(())
    if key is not None:
        kf = int(sketch["key_frame"])
        rel_p = p[:, kf] - p[:, kf, :1]
        key = key.to(p.dtype)
        l_key = ((rel_p - (key - key[:, :1])) ** 2).sum((1, 2)).mean()
    return g, l_key
