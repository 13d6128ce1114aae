"""2D–3D alignment of the keypose and trajectory encoders (Sketch2Anim Sec. 5, Eqs. (10)–(13)).

After the generator is trained on 3D conditions, two 2D encoders — ``E^2D_tr`` for drawn
trajectories and ``E^2D_k`` for a drawn keypose (:class:`~physlab.motion.model.
ControlledDenoiser` ``sketch_encoders``) — learn to put a drawing where the frozen 3D encoders
put the 3D condition it was drawn from, so that the frozen ControlNet and adapter can take a
sketch directly. Training pairs are made on the fly: a training window's random 3D condition
(:func:`~physlab.motion.train.condition_batch`) and its projection in a random storyboard
view with the augmentations of supp. B (:func:`sketch_batch`).

The loss (:func:`alignment_losses`) is Eq. (13),
``L_align = L_match + λ_r L_recon + λ_c L_contrast``:

* ``L_match`` (Eq. (10); the paper prints it with a minus sign, which would push the pairs
  apart — it is minimised as a distance): mean squared distance between ``s^3D`` and
  ``s^2D``, per token for the trajectory (``(B, T, C)``), per pose for the keypose ``(B, C)``;
* ``L_recon`` (Eq. (11)): the diffusion loss of the frozen generator run with the 2D
  embeddings in place of the 3D ones (here on the network's x̂₀ output, the target that the
  generator was trained with; the paper's ε is the same loss under another parametrisation).
  **physlab adds the control terms of Eq. (9)**, ``λ_tr L_tr + λ_key L_key`` (Eqs. (6), (8):
  the decoded x̂₀ against the 3D trajectory and keypose the drawing was made from), i.e. the
  whole loss the generator itself was trained with. Measured on 16 held-out windows: after
  1000 steps with Eq. (11) alone, the networks-only projected trajectory error was 0.116
  against 0.145 for text only (the drawing barely steered the motion; a lifting network fed to
  the 3D generator reached 0.088); the control terms say *where* the motion must go, which
  the noise reconstruction leaves to the 3D embeddings to imply;
* ``L_contrast`` (Eq. (12)): CLIP-style InfoNCE over the batch on the cosine similarity of
  the (token-averaged) embeddings, temperature ``τ₁``; each 3D embedding must pick its own
  drawing among the batch's.

**Departure from the paper: the 2D encoders see the camera.** Sketch2Anim's 2D encoders get
the drawing alone. physlab's also get the view (:func:`~physlab.motion.model.
camera_features`: scale, pitch, yaw, roll), which the storyboard editor knows anyway; a
drawing in an unknown view leaves depth and facing ambiguous, and the embedding of a
trajectory in the canonical 3D frame (frame 0 facing ``+z``) depends on the yaw.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from .camera import (JOINT_NOISE, PROPORTION_RANGE, Camera, random_camera,
                     perturb_proportions)

__all__ = ["sketch_batch", "camera_projections", "alignment_losses", "ALIGN_TERMS",
           "DEFAULT_TAU"]

#: Temperature τ₁ of Eq. (12) (CLIP's initial value is 0.07; the paper gives none).
DEFAULT_TAU = 0.1
#: Names of the terms of Eq. (13), as :func:`alignment_losses` reports them.
ALIGN_TERMS = ("match", "recon", "contrast")


def sketch_batch(cond, rng, noise=JOINT_NOISE, proportions=PROPORTION_RANGE, cameras=None):
    """The 2D drawing of a batch of 3D conditions (supp. B), as extra condition entries.

    Each sample gets a :func:`~physlab.motion.camera.random_camera` (pitch 0–30°, yaw ±45°,
    scale 0.8–1.2, roll 0) unless ``cameras`` are given; its keypose and trajectory points are
    projected (:meth:`~physlab.motion.camera.Camera.project`), the keypose's legs, spine and
    arms are rescaled by factors drawn from ``proportions``
    (:func:`~physlab.motion.camera.perturb_proportions`; None = off), and Gaussian noise of
    std ``noise`` is added to every drawn point.

    Parameters
    ----------
    cond : dict of a :func:`~physlab.motion.train.condition_batch` (``trajectory`` (B, N, 6, 3),
        ``traj_mask`` (B, N, 6), ``keypose`` (B, 22, 3)).
    rng : numpy Generator. noise : float >= 0. proportions : (low, high) or None.
    cameras : None or a list of B :class:`~physlab.motion.camera.Camera`.

    Returns
    -------
    dict of tensors: ``trajectory_2d`` (B, N, 6, 2) float32 (zeros where masked),
    ``traj_mask_2d`` (B, N, 6) bool (= ``traj_mask``), ``keypose_2d`` (B, 22, 2),
    ``camera`` (B, 4) ``[scale, pitch, yaw, roll]``.
    """
    traj = cond["trajectory"].double().numpy()
    key = cond["keypose"].double().numpy()
    mask = cond["traj_mask"].numpy()
    B = traj.shape[0]
    if cameras is None:
        cameras = [random_camera(rng) for _ in range(B)]
    if len(cameras) != B:
        raise ValueError(f"cameras must hold one Camera per sample ({B}), got {len(cameras)}")
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be a finite number >= 0, got {noise!r}")
    t2, k2 = np.empty(traj.shape[:-1] + (2,)), np.empty(key.shape[:-1] + (2,))
    for b, cam in enumerate(cameras):
        t2[b] = cam.project(traj[b])
        k = cam.project(key[b])
        if proportions is not None:
            k, _ = perturb_proportions(k, rng, factor=proportions)
        k2[b] = k
    if noise:
        t2 = t2 + rng.normal(0.0, noise, t2.shape)
        k2 = k2 + rng.normal(0.0, noise, k2.shape)
    t2 = t2 * mask[..., None]
    cam = np.array([[c.scale, c.pitch, c.yaw, c.roll] for c in cameras])
    return {"trajectory_2d": torch.tensor(t2, dtype=torch.float32),
            "traj_mask_2d": cond["traj_mask"].clone(),
            "keypose_2d": torch.tensor(k2, dtype=torch.float32),
            "camera": torch.tensor(cam, dtype=torch.float32)}


def camera_projections(camera):
    """``(B, 2, 3)`` float32 projection matrices ``s · R[:2]``
    (:attr:`~physlab.motion.camera.Camera.projection_matrix`) of a :func:`sketch_batch`
    ``camera`` tensor ``(B, 4)`` (scale, pitch, yaw, roll in degrees)."""
    cam = torch.as_tensor(camera).double()
    if cam.ndim != 2 or cam.shape[1] != 4:
        raise ValueError(f"camera must have shape (B, 4) [scale, pitch, yaw, roll], got "
                         f"{tuple(cam.shape)}")
    mats = [Camera(*c).projection_matrix for c in cam.tolist()]
    return torch.tensor(np.stack(mats), dtype=torch.float32)


def _info_nce(s3, s2, tau):
    """Eq. (12) for one condition type: ``-mean_i log softmax_j(sim(s3_i, s2_j) / τ)_i``."""
    logits = F.normalize(s3, dim=-1) @ F.normalize(s2, dim=-1).T / tau     # (B, B)
    return F.cross_entropy(logits, torch.arange(len(s3)))


def alignment_losses(model, x_t, t, text_emb, cond, sketch, target, drop_text=None,
                     tau=DEFAULT_TAU, recon=True, generation_loss=None):
    """The three terms of Eq. (13) for one batch.

    Parameters
    ----------
    model : :class:`~physlab.motion.model.ControlledDenoiser` with sketch encoders.
    x_t, t, text_emb, drop_text : the noisy training batch, as in the control stage.
    cond : 3D condition dict; sketch : :func:`sketch_batch` of it.
    target : the generator's training target for ``x_t`` (x₀ / ε / v).
    tau : τ₁ of Eq. (12). recon : compute ``L_recon`` (a pass through the frozen generator;
        False returns 0 for it, for the ablation without it).
    generation_loss : optional ``f(network output) -> scalar`` added to ``L_recon``: the rest
        of the loss the generator was trained with (physlab: the control terms
        ``λ_tr L_tr + λ_key L_key`` of Eq. (9) on the decoded x̂₀, module docstring).

    Returns
    -------
    dict ``match``, ``recon``, ``contrast`` of scalar tensors.
    """
    with torch.no_grad():
        s3_tr, s3_k = model.condition_embeddings(cond)                      # frozen 3D
    both = {**cond, **sketch}
    s2_tr, s2_k = model.condition_embeddings(both)                          # trainable 2D
    match = F.mse_loss(s2_tr, s3_tr) + F.mse_loss(s2_k, s3_k)               # Eq. (10)
    contrast = (_info_nce(s3_tr.mean(1), s2_tr.mean(1), tau)
                + _info_nce(s3_k, s2_k, tau))                               # Eq. (12)
    rec = x_t.new_zeros(())
    if recon:
        # Eq. (11) with the s^2D above: the 2D encoders run (and back-propagate) once per
        # batch, not again inside the generator (align steps 1.2x faster; the same loss)
        out = model(x_t, t, text_emb, {**both, "embeddings": (s2_tr, s2_k)}, drop_text)
        rec = F.mse_loss(out, target)
        if generation_loss is not None:
            rec = rec + generation_loss(out)
    return {"match": match, "recon": rec, "contrast": contrast}
