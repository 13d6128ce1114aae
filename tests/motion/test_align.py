"""2D–3D alignment (Sec. 5): the drawn training pairs are the camera's projections of the 3D
conditions, the camera features, the loss terms of Eqs. (10)–(13) against hand computations
(Eq. (12) is log B when the 2D embeddings cannot tell samples apart), gradients reach only the
2D encoders, and the 2D path of the controlled model."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from physlab.motion.align import _info_nce, alignment_losses, sketch_batch
from physlab.motion.camera import Camera
from physlab.motion.dataset import TRAJECTORY_JOINTS
from physlab.motion.model import (ControlledDenoiser, DenoiserConfig, MotionDenoiser,
                                  camera_features, check_condition)
from physlab.motion.train import condition_batch

from .test_model import _walk

CFG = DenoiserConfig(d_model=32, n_heads=2, n_layers=2, ff=64, dropout=0.0, representation="absolute",
                     feature_dim=70, n_frames=40)


def _model():
    torch.manual_seed(0)
    return ControlledDenoiser(MotionDenoiser(CFG), sketch_encoders=True).eval()


def _cond(B=4, seed=0):
    rng = np.random.default_rng(seed)
    windows = np.stack([_walk(40, seed=k) for k in range(B)])
    return condition_batch(windows, rng), rng


def test_sketch_batch_is_the_projection_of_the_3d_condition():
    cond, rng = _cond()
    cams = [Camera(1.0, 0, 0), Camera(0.9, 20, 30), Camera(1.2, 10, -45), Camera(1, 30, 5)]
    sk = sketch_batch(cond, rng, noise=0.0, proportions=None, cameras=cams)
    check_condition({**cond, **sk}, 4, 40)
    for b, cam in enumerate(cams):
        m = cond["traj_mask"][b].numpy()
        want = cam.project(cond["trajectory"][b].double().numpy())
        np.testing.assert_allclose(sk["trajectory_2d"][b].numpy()[m], want[m], atol=1e-5)
        assert not sk["trajectory_2d"][b].numpy()[~m].any()
        np.testing.assert_allclose(sk["keypose_2d"][b].numpy(),
                                   cam.project(cond["keypose"][b].double().numpy()), atol=1e-5)
        np.testing.assert_allclose(sk["camera"][b].numpy(), [cam.scale, cam.pitch, cam.yaw, 0],
                                   atol=1e-5)
    noisy = sketch_batch(cond, np.random.default_rng(1), noise=0.02, cameras=cams)
    d = (noisy["keypose_2d"] - sk["keypose_2d"]).numpy()
    assert 0 < np.abs(d).mean() < 0.5                    # noise + proportions moved the pose
    with pytest.raises(ValueError, match="one Camera per sample"):
        sketch_batch(cond, rng, cameras=cams[:2])
    r = sketch_batch(cond, np.random.default_rng(2))["camera"].numpy()         # supp. B ranges
    assert np.all((0.8 <= r[:, 0]) & (r[:, 0] <= 1.2) & (0 <= r[:, 1]) & (r[:, 1] <= 30))
    assert np.all(np.abs(r[:, 2]) <= 45) and not r[:, 3].any()


def test_camera_features():
    f = camera_features(torch.tensor([[1.2, 30.0, -90.0, 0.0]]))
    np.testing.assert_allclose(f.numpy()[0], [0.2, 0.5, -1.0, 0.0, math.sqrt(3) / 2, 0.0, 1.0],
                               atol=1e-6)
    with pytest.raises(ValueError, match=r"shape \(B, 4\)"):
        camera_features(torch.zeros(2, 3))


def test_alignment_terms_match_their_equations_and_train_only_the_2d_encoders():
    model = _model()
    cond, rng = _cond()
    sk = sketch_batch(cond, rng)
    B = 4
    x_t = torch.randn(B, CFG.n_frames, CFG.feature_dim)
    t = torch.tensor([10, 100, 400, 900])
    a = torch.randn(B, CFG.text_dim)
    target = torch.randn_like(x_t)
    terms = alignment_losses(model, x_t, t, a, cond, sk, target, tau=0.1)
    s3_tr, s3_k = model.condition_embeddings(cond)
    s2_tr, s2_k = model.condition_embeddings({**cond, **sk})
    want = ((s2_tr - s3_tr) ** 2).mean() + ((s2_k - s3_k) ** 2).mean()          # Eq. (10)
    torch.testing.assert_close(terms["match"], want)
    torch.testing.assert_close(terms["recon"], F.mse_loss(model(x_t, t, a, {**cond, **sk}),
                                                          target))          # Eq. (11)
    loss = sum(terms.values())
    loss.backward()
    for name, p in model.named_parameters():
        if name.startswith("sketch_"):
            assert p.grad is not None and torch.isfinite(p.grad).all(), name
        elif p.grad is not None:
            assert p.requires_grad and name.startswith(("controlnet", "adapter")), name
    # Eq. (12): with 2D embeddings that are the same for every sample, each row of the
    # similarity matrix is constant and the loss is log B per condition type
    with torch.no_grad():
        for enc in (model.sketch_traj_encoder.out, model.sketch_keypose_encoder.out):
            enc.weight.zero_()
            enc.bias.fill_(0.3)
    plus = alignment_losses(model, x_t, t, a, cond, sk, target,
                            generation_loss=lambda out: 0.0 * out.sum() + 1.5)   # Eq. (9) hook
    torch.testing.assert_close(plus["recon"], terms["recon"] + 1.5)
    flat = alignment_losses(model, x_t, t, a, cond, sk, target, recon=False)
    assert flat["contrast"].item() == pytest.approx(2 * math.log(B), rel=1e-5)
    assert flat["recon"].item() == 0.0


def test_2d_conditions_need_encoders_and_a_camera():
    cond, rng = _cond(2)
    sk = sketch_batch(cond, rng)
    plain = ControlledDenoiser(MotionDenoiser(CFG))
    x = torch.randn(2, CFG.n_frames, CFG.feature_dim)
    t, a = torch.tensor([5, 50]), torch.randn(2, CFG.text_dim)
    with pytest.raises(ValueError, match="no 2D encoders"):
        plain(x, t, a, {**cond, **sk})
    no_cam = {k: v for k, v in {**cond, **sk}.items() if k != "camera"}
    with pytest.raises(ValueError, match="no 'camera'"):
        _model()(x, t, a, no_cam)
    bad = {**cond, **sk, "keypose_2d": torch.zeros(2, 22, 3)}
    with pytest.raises(ValueError, match=r"keypose_2d'\] must have shape \(2, 22, 2\)"):
        _model()(x, t, a, bad)
    with pytest.raises(ValueError, match="single-ControlNet ablation has no 2D encoders"):
        ControlledDenoiser(MotionDenoiser(CFG), single_controlnet=True, sketch_encoders=True)
    m = _model()
    with torch.no_grad():                        # Z' starts at zero: open the adapter's path
        for z in m.adapter.zero:
            z.weight.normal_(0.0, 0.1)
    out2d = m(x, t, a, {**cond, **sk})
    out3d = m(x, t, a, cond)
    assert out2d.shape == out3d.shape and not torch.allclose(out2d, out3d)
    assert len(TRAJECTORY_JOINTS) == sk["trajectory_2d"].shape[2]


def test_alignment_losses_encode_the_drawing_once_with_the_gradient_of_eq_13():
    """L_recon reuses the 2D embeddings of L_match (one pass of the 2D encoders per batch):
    the loss and the 2D encoders' gradients equal Eq. (13) written out with the generator
    encoding the drawing itself."""
    cond, rng = _cond()
    sk = sketch_batch(cond, rng)
    x_t = torch.randn(4, CFG.n_frames, CFG.feature_dim)
    t = torch.tensor([10, 100, 400, 900])
    a = torch.randn(4, CFG.text_dim)
    target = torch.randn_like(x_t)
    model = _model()
    calls = []
    run = model.sketch_traj_encoder.forward
    model.sketch_traj_encoder.forward = lambda *args: calls.append(1) or run(*args)
    terms = alignment_losses(model, x_t, t, a, cond, sk, target, tau=0.1)
    assert len(calls) == 1
    sum(terms.values()).backward()
    got = {n: p.grad.clone() for n, p in model.named_parameters() if n.startswith("sketch_")}
    ref = _model()
    s3_tr, s3_k = ref.condition_embeddings(cond)
    s2_tr, s2_k = ref.condition_embeddings({**cond, **sk})
    s3_tr, s3_k = s3_tr.detach(), s3_k.detach()
    want = (F.mse_loss(s2_tr, s3_tr) + F.mse_loss(s2_k, s3_k)                       # (10)
            + F.mse_loss(ref(x_t, t, a, {**cond, **sk}), target)                     # (11)
            + _info_nce(s3_tr.mean(1), s2_tr.mean(1), 0.1) + _info_nce(s3_k, s2_k, 0.1))
    torch.testing.assert_close(sum(terms.values()).detach(), want.detach())
    want.backward()
    for n, p in ref.named_parameters():
        if n.startswith("sketch_"):
            torch.testing.assert_close(got[n], p.grad, rtol=1e-4, atol=1e-6, msg=n)
