"""Tests of physlab.motion.model: shapes, the zero-init property of ControlNet / adapter
(Sketch2Anim Eqs. (1)–(4)), an overfit sanity check, and the torch features -> joints decoder
against the numpy inverse."""
import dataclasses

import numpy as np
import pytest
import torch

from physlab.motion.features import canonicalize, features_to_joints, joints_to_features
from physlab.motion.model import (
    ControlledDenoiser,
    DenoiserConfig,
    Dropout,
    MotionDenoiser,
    count_parameters,
    features_to_joints_torch,
    timestep_embedding,
)

TINY = {"d_model": 32, "n_heads": 2, "n_layers": 2, "ff": 64, "dropout": 0.0}


def _inputs(B=3, seed=0, cfg=None):
    cfg = cfg or DenoiserConfig(**TINY)
    g = torch.Generator().manual_seed(seed)
    N = cfg.n_joint_frames
    x = torch.randn(B, cfg.n_frames, cfg.feature_dim, generator=g)          # (B, T, D)
    t = torch.randint(0, cfg.max_timesteps, (B,), generator=g)
    a = torch.randn(B, cfg.text_dim, generator=g)
    cond = {"trajectory": torch.randn(B, N, 6, 3, generator=g),
            "traj_mask": torch.rand(B, N, 6, generator=g) > 0.5,
            "keypose": torch.randn(B, 22, 3, generator=g),
            "key_frame": torch.tensor([0, N - 1, 0][:B] + [0] * max(0, B - 3))}
    return x, t, a, cond


def _walk(T=40, seed=0):
    """A smooth synthetic 22-joint motion (T, 22, 3), canonicalised (not a real body, but
    hips and shoulders define a heading in every frame)."""
    rng = np.random.default_rng(seed)
    rest = rng.normal(scale=0.3, size=(22, 3))
    rest[[1, 2, 16, 17]] = [[0.1, 0, 0], [-0.1, 0, 0], [0.2, 0.5, 0], [-0.2, 0.5, 0]]
    time = np.arange(T)[:, None, None] / 20.0
    wobble = 0.05 * np.sin(2 * np.pi * (0.7 * time + rng.random((1, 22, 3))))
    x = rest[None] + wobble + np.array([0.3, 1.0, 1.2]) * time * np.array([1, 0, 1])
    yaw = 0.4 * np.sin(time[:, 0, 0])
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x = np.stack([c * x[..., 0] + s * x[..., 2], x[..., 1] + 0.9, -s * x[..., 0] + c * x[..., 2]],
                 axis=-1)
    return canonicalize(x, ground=False)


# ----------------------------------------------------------------------------- config


def test_default_config_and_parameter_counts():
    cfg = DenoiserConfig()
    assert (cfg.feature_dim, cfg.n_frames, cfg.n_joint_frames) == (137, 39, 40)
    base = MotionDenoiser(cfg)
    ctrl = ControlledDenoiser(base)
    # reference numbers of the default size (README of the training run)
    assert count_parameters(base) == 916_489
    assert count_parameters(ctrl, trainable_only=True) == count_parameters(ctrl) - 916_489
    assert count_parameters(ctrl) * 2 < 25e6          # fp16 inference checkpoint < 25 MB
    assert DenoiserConfig.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize("bad, match", [
    ({"d_model": 30, "n_heads": 4}, "divisible"),
    ({"n_layers": 0}, "n_layers"),
    ({"dropout": 1.5}, "dropout"),
    ({"cond_drop_prob": -0.1}, "cond_drop_prob"),
])
def test_config_rejects_bad_values(bad, match):
    with pytest.raises(ValueError, match=match):
        DenoiserConfig(**bad)
    with pytest.raises(ValueError, match="unknown"):
        DenoiserConfig.from_dict({"d_modle": 3})


def test_timestep_embedding_analytic():
    e = timestep_embedding(torch.tensor([0, 5]), 8)
    assert e.shape == (2, 8)
    assert torch.equal(e[0], torch.tensor([1.0] * 4 + [0.0] * 4))       # cos 0, sin 0
    assert torch.allclose(e[1, 0], torch.cos(torch.tensor(5.0)))


# ----------------------------------------------------------------------------- networks


def test_shapes_base_controlled_single():
    cfg = DenoiserConfig(**TINY)
    base = MotionDenoiser(cfg).eval()
    x, t, a, cond = _inputs(cfg=cfg)
    assert base(x, t, a).shape == x.shape
    assert base(x, t, a, drop_text=torch.tensor([True, False, True])).shape == x.shape
    for single in (False, True):
        ctrl = ControlledDenoiser(base, single_controlnet=single).eval()
        assert ctrl(x, t, a, cond).shape == x.shape
        assert (ctrl.adapter is None) == single
    double = ControlledDenoiser(base, double_controlnet=True).eval()
    assert double(x, t, a, cond).shape == x.shape and double.adapter is not None
    with pytest.raises(ValueError, match="at most one"):
        ControlledDenoiser(base, single_controlnet=True, double_controlnet=True)


def test_given_condition_embeddings_give_the_same_output_and_are_checked():
    """The sampler encodes a clip's conditions once and hands them in as cond["embeddings"]:
    the output must be exactly what encoding them in forward gives."""
    cfg = DenoiserConfig(**TINY)
    torch.manual_seed(0)
    ctrl = ControlledDenoiser(MotionDenoiser(cfg)).eval()
    with torch.no_grad():                   # trained-like: the zero layers let conditions in
        for z in list(ctrl.controlnet.zero) + list(ctrl.adapter.zero):
            z.weight.normal_(0.0, 0.1)
    x, t, a, cond = _inputs(cfg=cfg)
    want = ctrl(x, t, a, cond)
    other = dict(cond, trajectory=cond["trajectory"] + 1.0, keypose=cond["keypose"] - 1.0)
    assert not torch.allclose(ctrl(x, t, a, other), want)           # the conditions matter
    emb = ctrl.condition_embeddings(cond)
    assert torch.equal(ctrl(x, t, a, dict(cond, embeddings=emb)), want)
    assert torch.equal(ctrl(x, t, a, dict(other, embeddings=emb)), want)   # emb is what is read
    for bad in ((emb[0],), (emb[0], emb[1][:1]), "emb"):
        with pytest.raises(ValueError, match=r"cond\['embeddings'\] must be the pair"):
            ctrl(x, t, a, dict(cond, embeddings=bad))


@pytest.mark.parametrize("p", [0.1, 0.3, 0.5])
@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
def test_dropout_is_inverted_dropout_with_the_asked_rate(p, dtype):
    """physlab's cheaper dropout keeps nn.Dropout's contract: an element survives with
    probability 1 - p (binomial bound, 5 sigma over 10^6 draws), survivors are scaled by
    1 / (1 - p) (p rounded to a multiple of 2**-16), the expectation is unchanged, and the
    gradient is the same mask."""
    torch.manual_seed(0)
    n = 1_000_003                                       # not a multiple of 4 (bits per draw)
    x = torch.full((n,), 2.0, dtype=dtype, requires_grad=True)
    drop = Dropout(p).train()
    y = drop(x)
    kept = y != 0
    frac = kept.double().mean().item()
    assert abs(frac - (1 - p)) < 5 * (p * (1 - p) / n) ** 0.5
    k = round(p * 65536)                                # p is rounded to k / 65536
    assert abs(65536 / (65536 - k) - 1 / (1 - p)) < 2**-15
    scale = 2 * torch.tensor(65536 / (65536 - k), dtype=dtype)
    assert torch.equal(y[kept], scale.expand(int(kept.sum())))
    assert abs(y.double().mean().item() - 2.0) < 5 * 2.0 * (p / (1 - p) / n) ** 0.5 + 0.01
    y.sum().backward()
    assert torch.equal(x.grad, y.detach() / 2)
    # masks along the tensor are independent of each other: neighbours' keep rates agree
    rates = kept.view(-1)[: n - n % 4].view(-1, 4).double().mean(0)
    assert torch.all((rates - (1 - p)).abs() < 5 * (p * (1 - p) / (n / 4)) ** 0.5)


def test_dropout_is_the_identity_in_eval_and_at_zero_and_refuses_bad_rates():
    x = torch.randn(3, 5, 7)
    assert Dropout(0.1).eval()(x) is x
    assert Dropout(0.0).train()(x) is x
    assert Dropout(2**-18).train()(x) is x                # rounds to 0 of 65536
    torch.manual_seed(3)
    a = Dropout(0.1).train()(x)
    torch.manual_seed(3)
    assert torch.equal(Dropout(0.1).train()(x), a)            # seeded like nn.Dropout
    for bad in (-0.1, 1.0, float("nan"), "0.1"):
        with pytest.raises(ValueError, match="dropout probability"):
            Dropout(bad)
    # no state: a model's keys are those it had with nn.Dropout
    assert Dropout(0.1).state_dict() == {} and "p=0.1" in repr(Dropout(0.1))


def test_zero_init_controlled_equals_base_exactly():
    cfg = DenoiserConfig(**TINY)
    base = MotionDenoiser(cfg).eval()
    x, t, a, cond = _inputs(cfg=cfg)
    drop = torch.tensor([False, True, False])
    ref = base(x, t, a, drop)
    for single, double in ((False, False), (True, False), (False, True)):
        ctrl = ControlledDenoiser(base, single_controlnet=single,
                                  double_controlnet=double).eval()
        assert torch.equal(ctrl(x, t, a, cond, drop), ref)
        with torch.no_grad():
            assert torch.equal(ctrl(x, t, a, cond, drop), ref)
        # the copies start from the base weights, the base is frozen
        sd_b, sd_c = base.encoder.state_dict(), ctrl.controlnet.encoder.state_dict()
        assert all(torch.equal(sd_b[k], sd_c[k]) for k in sd_b)
        assert not any(p.requires_grad for p in ctrl.base.parameters())


def test_double_controlnet_runs_its_branches_side_by_side():
    """Table 2's double ControlNet: the keypose branch does not see the trajectory
    ControlNet's residuals (in the adapter it does), the two residual lists are added, and
    both branches learn from the first step (both zero layers start at 0)."""
    cfg = DenoiserConfig(**TINY)
    base = MotionDenoiser(cfg).eval()
    x, t, a, cond = _inputs(cfg=cfg)
    other = {**cond, "trajectory": cond["trajectory"] + 1.0}
    for double in (False, True):
        ctrl = ControlledDenoiser(base, double_controlnet=double).eval()
        with torch.no_grad():                              # non-zero output layers
            for z in [*ctrl.controlnet.zero, *ctrl.adapter.zero]:
                z.weight.normal_(0.0, 0.1)
        e_k = ctrl.condition_embeddings(cond)[1]
        res = []
        for c in (cond, other):
            r = ctrl.controlnet.from_embedding(x, t, a, ctrl.condition_embeddings(c)[0])
            rk = ctrl.adapter.from_embedding(x, t, a, e_k, None if double else r)
            res.append(rk)
            if double:                                     # forward = base on r + r'
                total = [u + v for u, v in zip(r, rk)]
                assert torch.allclose(ctrl(x, t, a, c), base(x, t, a, residuals=total))
        same = all(torch.equal(u, v) for u, v in zip(*res))
        assert same == double
    ctrl = ControlledDenoiser(base, double_controlnet=True).train()
    ctrl(x, t, a, cond).square().mean().backward()
    for branch in (ctrl.controlnet, ctrl.adapter):
        assert all(float(z.weight.grad.abs().max()) > 0 for z in branch.zero)


def test_controls_change_output_after_one_step_and_base_stays_frozen():
    cfg = DenoiserConfig(**TINY)
    base = MotionDenoiser(cfg).eval()
    before = {k: v.clone() for k, v in base.state_dict().items()}
    ctrl = ControlledDenoiser(base).train()
    x, t, a, cond = _inputs(cfg=cfg)
    opt = torch.optim.Adam([p for p in ctrl.parameters() if p.requires_grad], lr=1e-3)
    for _ in range(2):
        opt.zero_grad()
        ctrl(x, t, a, cond).square().mean().backward()
        opt.step()
    ctrl.eval()
    assert not torch.equal(ctrl(x, t, a, cond), base(x, t, a))
    assert all(torch.equal(before[k], v) for k, v in base.state_dict().items())
    assert not base.training                        # frozen base stays in eval mode


def test_overfit_tiny_batch():
    torch.manual_seed(0)
    cfg = DenoiserConfig(**TINY)
    model = MotionDenoiser(cfg)
    x, t, a, _ = _inputs(B=4, cfg=cfg)
    target = torch.randn(x.shape, generator=torch.Generator().manual_seed(1))
    opt = torch.optim.Adam(model.parameters(), lr=3e-3)
    losses = []
    for _ in range(60):
        opt.zero_grad()
        loss = (model(x, t, a) - target).square().mean()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]


@pytest.mark.parametrize("change, match", [
    (lambda x, t, a, c: (x[:, :-1], t, a, c), "x_t must have shape"),
    (lambda x, t, a, c: (x.index_fill(1, torch.tensor([3]), float("nan")), t, a, c), "NaN"),
    (lambda x, t, a, c: (x, t.float(), a, c), "integer"),
    (lambda x, t, a, c: (x, t + 1000, a, c), "max_timesteps"),
    (lambda x, t, a, c: (x, t, a[:, :100], c), "text_emb"),
    (lambda x, t, a, c: (x, t, a, {**c, "keypose": c["keypose"][:, :21]}), "22 joints"),
    (lambda x, t, a, c: (x, t, a, {**c, "trajectory": torch.zeros(3, 40, 7, 3)}),
     "6 trajectory joints"),
    (lambda x, t, a, c: (x, t, a, {**c, "key_frame": torch.tensor([0, 40, 1])}), "0..39"),
    (lambda x, t, a, c: (x, t, a, {**c, "trajectory": c["trajectory"] * float("nan")}), "NaN"),
    (lambda x, t, a, c: (x, t, a, {"keypose": c["keypose"]}), "missing"),
])
def test_bad_inputs_raise_clear_errors(change, match):
    cfg = DenoiserConfig(**TINY)
    ctrl = ControlledDenoiser(MotionDenoiser(cfg)).eval()
    with pytest.raises(ValueError, match=match):
        ctrl(*change(*_inputs(cfg=cfg)))


# ----------------------------------------------------------------------------- decoding


def test_torch_decoding_matches_numpy_inverse():
    rng = np.random.default_rng(0)
    f = rng.normal(scale=0.1, size=(3, 39, 137))                            # any rows decode
    ref = np.stack([features_to_joints(fi) for fi in f])                    # (3, 40, 22, 3)
    out = features_to_joints_torch(torch.tensor(f)).numpy()
    assert out.shape == (3, 40, 22, 3)
    assert np.abs(out - ref).max() < 1e-12                                  # float64
    out32 = features_to_joints_torch(torch.tensor(f, dtype=torch.float32)).numpy()
    assert np.abs(out32 - ref).max() < 1e-5                                 # float32, metres
    no_last = features_to_joints_torch(torch.tensor(f), include_last=False).numpy()
    assert np.array_equal(no_last, out[:, :-1])


def test_torch_decoding_inverts_features_of_a_motion_and_has_gradients():
    x = _walk()
    f = torch.tensor(joints_to_features(x)[None], requires_grad=True)       # (1, 39, 137)
    j = features_to_joints_torch(f)
    assert np.abs(j[0].detach().numpy() - x).max() < 1e-10                  # exact inverse
    j[0, -1, 15].sum().backward()                                           # head, last frame
    assert f.grad.abs().sum() > 0 and torch.isfinite(f.grad).all()
    with pytest.raises(ValueError, match="137"):
        features_to_joints_torch(torch.zeros(1, 39, 136))


def test_torch_decoding_of_absolute_features_matches_numpy():
    from physlab.motion.features import absolute_features_to_joints

    f = np.random.default_rng(1).normal(scale=0.3, size=(2, 40, 70))
    out = features_to_joints_torch(torch.tensor(f), representation="absolute").numpy()
    np.testing.assert_allclose(out, np.stack([absolute_features_to_joints(a) for a in f]),
                               atol=1e-12)
    with pytest.raises(ValueError, match=r"shape \(B, T, 70\)"):
        features_to_joints_torch(torch.zeros(1, 40, 137), representation="absolute")


def test_absolute_config_frame_encoder_and_keypose_mask():
    from physlab.motion.model import (ControlledDenoiser, DenoiserConfig, MotionDenoiser)

    cfg = DenoiserConfig.for_representation("absolute", d_model=32, n_heads=2, n_layers=2,
                                            ff=64, dropout=0.0)
    assert (cfg.feature_dim, cfg.n_frames, cfg.n_joint_frames) == (70, 40, 40)
    assert DenoiserConfig().n_joint_frames == 40                            # relative: 39 rows
    torch.manual_seed(0)
    m = ControlledDenoiser(MotionDenoiser(cfg))
    for p in list(m.controlnet.zero.parameters()) + list(m.adapter.zero.parameters()):
        torch.nn.init.normal_(p, std=0.1)                                   # "trained" outputs
    B = 2
    x, t, a = torch.randn(B, 40, 70), torch.tensor([5, 500]), torch.randn(B, 384)
    cond = {"trajectory": torch.randn(B, 40, 6, 3), "traj_mask": torch.ones(B, 40, 6, dtype=torch.bool),
            "keypose": torch.randn(B, 22, 3), "key_frame": torch.tensor([0, 39])}
    m.eval()
    with torch.no_grad():
        full = m(x, t, a, cond)
        off = m(x, t, a, {**cond, "keypose_mask": torch.tensor([False, True])})
        other = m(x, t, a, {**cond, "keypose": torch.randn(B, 22, 3),
                            "keypose_mask": torch.tensor([False, True])})
    assert full.shape == (B, 40, 70)
    assert torch.equal(off[1], full[1]) and not torch.allclose(off[0], full[0])
    assert torch.equal(other[0], off[0])            # a masked keypose has no effect at all
    with pytest.raises(ValueError, match="keypose_mask"):
        m(x, t, a, {**cond, "keypose_mask": torch.tensor([1, 0])})


def test_low_pass_matrix_is_the_dct_projection_and_smooths_the_output():
    from scipy.fft import dct, idct

    from physlab.motion.model import DenoiserConfig, MotionDenoiser, low_pass_matrix

    P = low_pass_matrix(40, 16).double()
    x = np.random.default_rng(0).normal(size=(40, 5))
    c = dct(x, axis=0, norm="ortho")
    c[16:] = 0
    np.testing.assert_allclose(P.numpy() @ x, idct(c, axis=0, norm="ortho"), atol=1e-6)
    assert torch.allclose(P @ P, P, atol=1e-6) and torch.allclose(P, P.T)
    cfg = DenoiserConfig.for_representation("absolute", d_model=32, n_heads=2, n_layers=1,
                                            ff=64, smooth_basis=8)
    torch.manual_seed(0)
    m = MotionDenoiser(cfg).eval()
    with torch.no_grad():
        out = m(torch.randn(2, 40, 70), torch.tensor([3, 900]), torch.randn(2, 384))
    assert np.abs(dct(out.numpy(), axis=1, norm="ortho"))[:, 8:].max() < 1e-5  # k >= 8: none
    assert "low_pass" not in m.state_dict()                       # a fixed, rebuilt buffer
    for bad in (-1, 41, 2.5, True):
        with pytest.raises(ValueError, match="smooth_basis must be an integer"):
            DenoiserConfig.for_representation("absolute", smooth_basis=bad)


def test_skip_connection_is_the_linear_guess_plus_a_scaled_correction():
    """``config.skip``: x̂₀ = √ᾱ_t x_t + √(1 − ᾱ_t) F. With the head zeroed (F = 0) the
    output is exactly √ᾱ_t x_t (then low-passed); F enters scaled by √(1 − ᾱ_t)."""
    from physlab.motion.diffusion import NoiseScheduler, SchedulerConfig

    abar = NoiseScheduler(SchedulerConfig()).alphas_cumprod
    cfg = DenoiserConfig.for_representation("absolute", d_model=32, n_heads=2, n_layers=1,
                                            ff=64, skip=True)
    torch.manual_seed(0)
    m = MotionDenoiser(cfg).eval()
    x, t, a = torch.randn(2, 40, 70), torch.tensor([0, 999]), torch.randn(2, 384)
    with pytest.raises(RuntimeError, match="set_schedule"):
        m(x, t, a)
    plain = MotionDenoiser(dataclasses.replace(cfg, skip=False)).eval()
    plain.load_state_dict(m.state_dict())
    m.set_schedule(abar)
    assert "skip_scale" not in m.state_dict()             # from the scheduler, not the weights
    with torch.no_grad():
        F, out = plain(x, t, a), m(x, t, a)
        s = abar[t].sqrt().float()[:, None, None]
        torch.testing.assert_close(out, s * x + (1 - s ** 2).sqrt() * F)
        torch.nn.init.zeros_(m.head.weight)
        torch.nn.init.zeros_(m.head.bias)
        torch.testing.assert_close(m(x, t, a), s * x)
    for bad in (abar[:10], torch.zeros(1000), abar * 2):
        with pytest.raises(ValueError, match="alphas_cumprod"):
            m.set_schedule(bad)
    with pytest.raises(ValueError, match="skip must be True or False"):
        DenoiserConfig(skip=1)
    assert plain.set_schedule(torch.zeros(3)) is plain    # no skip connection: ignored
    # skip_pelvis=False: the pelvis position columns stay plain x0 (F), the rest skip
    nop = MotionDenoiser(dataclasses.replace(cfg, skip_pelvis=False)).eval()
    nop.load_state_dict(m.state_dict())
    nop.set_schedule(abar)
    with torch.no_grad():
        y = nop(x, t, a)
    from physlab.motion.features import ABS_PELVIS
    torch.testing.assert_close(y[..., ABS_PELVIS], torch.zeros_like(y[..., ABS_PELVIS]))
    torch.testing.assert_close(y[..., 3:], (s * x)[..., 3:])
    with pytest.raises(ValueError, match="skip_pelvis=False needs"):
        DenoiserConfig(skip=True, skip_pelvis=False)          # "relative" features


def test_control_head_starts_at_zero_and_acts_on_x0_unscaled_after_the_skip():
    """``ControlledDenoiser(control_head=True)``: zero at initialisation (the controlled model
    equals the base, for every Table 2 variant); its output is added to x̂₀ after the skip
    connection, not scaled by √(1 − ᾱ_t) as the residuals are — at t = 0 a residual moves x̂₀
    by √(1 − ᾱ_0) of what it moves F, the head by all of it; and it learns from step one."""
    from physlab.motion.diffusion import NoiseScheduler, SchedulerConfig

    abar = NoiseScheduler(SchedulerConfig()).alphas_cumprod
    cfg = DenoiserConfig.for_representation("absolute", d_model=32, n_heads=2, n_layers=2,
                                            ff=64, skip=True, skip_pelvis=False)
    torch.manual_seed(0)
    base = MotionDenoiser(cfg).eval().set_schedule(abar)
    x, t, a, cond = _inputs(B=2, cfg=cfg)
    t = torch.tensor([0, 0])
    ref = base(x, t, a)
    for single, double in ((False, False), (True, False), (False, True)):
        ctrl = ControlledDenoiser(base, single_controlnet=single, double_controlnet=double,
                                  control_head=True).eval()
        assert ctrl.control_head is not None
        assert torch.equal(ctrl(x, t, a, cond), ref)
        ctrl.train()
        ctrl(x, t, a, cond).square().mean().backward()
        assert float(ctrl.control_head[1].weight.grad.abs().max()) > 0
    assert ControlledDenoiser(base).control_head is None
    ctrl = ControlledDenoiser(base, control_head=True).eval()
    c = torch.linspace(-1, 1, cfg.feature_dim)
    with torch.no_grad():
        ctrl.control_head[1].bias.copy_(c)                  # H(h) = c for every row
        moved = ctrl(x, t, a, cond) - ref
        torch.testing.assert_close(moved, base.smooth(c.expand_as(x).clone()))
        ctrl.control_head[1].bias.zero_()
        # the same shift through the base's head (what the residuals reach) is scaled
        base.head.bias.add_(c)
        through_f = base(x, t, a) - ref
        base.head.bias.sub_(c)
    scale = float((1 - abar[0]) ** 0.5)
    skip_cols = torch.ones(cfg.feature_dim, dtype=torch.bool)
    from physlab.motion.features import ABS_PELVIS
    skip_cols[ABS_PELVIS] = False
    torch.testing.assert_close(through_f[..., skip_cols], scale * moved[..., skip_cols])
    assert scale < 0.1


def test_controlnet_variant_names_models_and_checkpoints_alike():
    from physlab.motion.model import controlnet_variant
    base = MotionDenoiser(DenoiserConfig(**TINY))
    assert ControlledDenoiser(base).variant == "adapter"
    assert ControlledDenoiser(base, single_controlnet=True).variant == "single"
    assert ControlledDenoiser(base, double_controlnet=True).variant == "double"
    assert controlnet_variant({"stage": "control"}) == "adapter"        # older checkpoints
    assert controlnet_variant({"single_controlnet": False, "double_controlnet": True}) == "double"
    with pytest.raises(ValueError, match="single_controlnet and double_controlnet"):
        controlnet_variant({"single_controlnet": True, "double_controlnet": True})


# ----------------------------------------------------------------------------- fused inference


def _randomised(module, seed):
    """Every parameter of ``module`` drawn at random (zero layers included), so that each
    branch changes the output."""
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for p in module.parameters():
            p.copy_(torch.randn(p.shape, generator=g) * 0.2)
    return module


@pytest.mark.parametrize("variant", ["adapter", "single", "double"])
@pytest.mark.parametrize("head", [False, True])
def test_fused_controlled_denoiser_equals_the_model(variant, head):
    """FusedControlledDenoiser runs the blocks of one depth of all encoders as one batched
    computation: its output must equal ControlledDenoiser.forward (eval mode) for every
    Table 2 variant, with and without the control head, skip connection, text dropout, a
    missing keypose and precomputed condition embeddings, and so must the gradient with
    respect to x_t (what the network-space guidance follows). Batch 2 differs from the 3 or 2
    stacked encoders, so a reshape that mixed them up would show."""
    from physlab.motion.diffusion import NoiseScheduler, SchedulerConfig
    from physlab.motion.model import FusedControlledDenoiser

    cfg = DenoiserConfig.for_representation("absolute", d_model=32, n_heads=2, n_layers=3,
                                            ff=64, skip=True, skip_pelvis=False)
    base = MotionDenoiser(cfg).set_schedule(NoiseScheduler(SchedulerConfig()).alphas_cumprod)
    ctrl = ControlledDenoiser(_randomised(base, 1), single_controlnet=variant == "single",
                              double_controlnet=variant == "double", control_head=head)
    ctrl = _randomised(ctrl, 2).eval()
    fused = FusedControlledDenoiser(ctrl)
    x, t, a, cond = _inputs(B=2, cfg=cfg)
    cond["keypose_mask"] = torch.tensor([True, False])
    drop = torch.tensor([False, True])
    conds = [cond]
    if variant != "single":
        with torch.no_grad():
            conds.append({**cond, "embeddings": ctrl.condition_embeddings(cond)})
    for c in conds:
        with torch.no_grad():
            ref, got = ctrl(x, t, a, c, drop), fused(x, t, a, c, drop)
            plain = ctrl.base(x, t, a, drop)
        assert float((ref - plain).abs().max()) > 0.1        # the branches act
        torch.testing.assert_close(got, ref, rtol=1e-5, atol=1e-5)
    grads = []
    for net in (ctrl, fused):
        z = x.clone().requires_grad_(True)
        net(z, t, a, cond, drop).square().sum().backward()
        grads.append(z.grad)
    torch.testing.assert_close(grads[1], grads[0], rtol=1e-4, atol=1e-4)


@pytest.mark.parametrize("S", [1, 2])
def test_stacked_blocks_equal_each_block(S):
    """StackedBlocks on S blocks = each Block on its own slice (eval mode), batch 3."""
    from physlab.motion.model import Block, StackedBlocks

    blocks = [_randomised(Block(16, 2, 32, 0.1), 10 + i).eval() for i in range(S)]
    h = torch.randn(S, 3, 5, 16, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        got = StackedBlocks(blocks)(h)
        ref = torch.stack([b(h[i]) for i, b in enumerate(blocks)])
    torch.testing.assert_close(got, ref, rtol=1e-5, atol=1e-5)


def test_stacked_blocks_refuse_mixed_or_no_blocks():
    from physlab.motion.model import Block, StackedBlocks

    with pytest.raises(ValueError, match="at least one"):
        StackedBlocks([])
    with pytest.raises(ValueError, match="one kind"):
        StackedBlocks([Block(16, 2, 32, 0.0), Block(16, 2, 64, 0.0)])
    tanh = Block(16, 2, 32, 0.0)
    tanh.mlp[1] = torch.nn.GELU(approximate="tanh")
    with pytest.raises(ValueError, match="GELU"):
        StackedBlocks([Block(16, 2, 32, 0.0), tanh])


def test_fused_controlled_denoiser_follows_weight_changes_and_inference_mode():
    """The stacked weights are copies: after load_state_dict (or any in-place write) the next
    call re-stacks them; built under torch.inference_mode() they still let gradients reach
    the input (the network-space guidance)."""
    from physlab.motion.model import FusedControlledDenoiser

    cfg = DenoiserConfig(**TINY)
    base = _randomised(MotionDenoiser(cfg), 1)
    ctrl = _randomised(ControlledDenoiser(base), 2).eval()
    x, t, a, cond = _inputs(B=2, cfg=cfg)
    with torch.inference_mode():
        fused = FusedControlledDenoiser(ctrl)
        fused(x, t, a, cond)
    other = _randomised(ControlledDenoiser(MotionDenoiser(cfg)), 3).eval()
    ctrl.load_state_dict(other.state_dict())
    with torch.no_grad():
        torch.testing.assert_close(fused(x, t, a, cond), other(x, t, a, cond),
                                   rtol=1e-5, atol=1e-5)
    z = x.clone().requires_grad_(True)
    fused(z, t, a, cond).sum().backward()
    assert z.grad is not None and float(z.grad.abs().max()) > 0


def test_fused_controlled_denoiser_refuses_training_mode_and_other_models():
    from physlab.motion.model import FusedControlledDenoiser

    base = MotionDenoiser(DenoiserConfig(**TINY))
    with pytest.raises(ValueError, match="eval"):
        FusedControlledDenoiser(ControlledDenoiser(base).train())
    ctrl = ControlledDenoiser(base).eval()
    ctrl.adapter.train()                                   # one branch with dropout on
    with pytest.raises(ValueError, match="eval"):
        FusedControlledDenoiser(ctrl)
    with pytest.raises(TypeError, match="ControlledDenoiser"):
        FusedControlledDenoiser(base)
