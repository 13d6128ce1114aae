"""Tests of physlab.motion.diffusion: schedules, forward process, DDPM / DDIM steps, the
sampling loop on an analytic Gaussian, classifier-free guidance, config round trip, errors."""
import json
import math

import numpy as np
import pytest
import torch

from physlab.motion.diffusion import (DEFAULT_GUIDANCE_SCALE, NoiseScheduler, SchedulerConfig,
                                      StepOutput, classifier_free_guidance, make_betas)

F64 = torch.float64


def _gen(seed=0):
    return torch.Generator().manual_seed(seed)


def _bcast(a, x):
    """(B,) schedule values -> (B, 1, ..., 1) in x's dtype."""
    return a.to(x.dtype).reshape(-1, *([1] * (x.ndim - 1)))


def _oracle(sched, x0):
    """A perfect ε-network for one fixed clean sample x0: the ε that produced x_t from x0."""
    def model_fn(x_t, t, cond=None):
        a = _bcast(sched.alphas_cumprod[t], x_t)
        return (x_t - a.sqrt() * x0) / (1 - a).sqrt()
    return model_fn


def _gaussian_eps(sched, mu, sigma):
    """The optimal ε-predictor E[ε | x_t] for data x0 ~ N(mu, sigma²)."""
    def model_fn(x_t, t, cond=None):
        a = _bcast(sched.alphas_cumprod[t], x_t)
        return (x_t - a.sqrt() * mu) * (1 - a).sqrt() / (a * sigma ** 2 + 1 - a)
    return model_fn


# ----------------------------------------------------------------------------- schedules


@pytest.mark.parametrize("schedule", ["linear", "scaled_linear", "cosine"])
def test_schedule_properties(schedule):
    s = NoiseScheduler(beta_schedule=schedule)
    assert s.betas.shape == s.alphas_cumprod.shape == (1000,)
    assert s.betas.dtype == F64
    assert bool(((s.betas > 0) & (s.betas < 1)).all())
    ab = s.alphas_cumprod
    assert bool(((ab > 0) & (ab < 1)).all())
    assert bool((ab[1:] < ab[:-1]).all())                       # strictly decreasing
    assert torch.allclose(ab, torch.cumprod(1 - s.betas, 0))
    assert float(ab[-1]) < 1e-3                                 # x_{T-1} is almost pure noise


def test_schedule_closed_forms_and_reference_numbers():
    lin = make_betas(1000, 1e-4, 0.02, "linear")
    assert float(lin[0]) == pytest.approx(1e-4) and float(lin[-1]) == pytest.approx(0.02)
    assert float(lin[1] - lin[0]) == pytest.approx((0.02 - 1e-4) / 999)
    sl = make_betas(1000, 0.00085, 0.012, "scaled_linear")     # MLD / Stable Diffusion
    assert float(sl[0]) == pytest.approx(0.00085) and float(sl[-1]) == pytest.approx(0.012)
    assert torch.allclose(sl.sqrt()[1:] - sl.sqrt()[:-1],
                          torch.full((999,), (0.012 ** 0.5 - 0.00085 ** 0.5) / 999, dtype=F64))
    # cosine: ᾱ_t = f(t + 1) / f(0) (Nichol & Dhariwal Eq. (17)) wherever β is not capped
    T = 1000
    f = lambda t: math.cos((t / T + 0.008) / 1.008 * math.pi / 2) ** 2
    ab = NoiseScheduler(beta_schedule="cosine").alphas_cumprod
    for t in (0, 10, 500, 900, 990):
        assert float(ab[t]) == pytest.approx(f(t + 1) / f(0), rel=1e-10)
    # fixed reference numbers (float64)
    assert float(NoiseScheduler().alphas_cumprod[-1]) == pytest.approx(4.035829e-05, rel=1e-5)
    # ∏_{i<500} (1 − β_i) by a plain Python loop: 0.0785872428817782
    assert float(NoiseScheduler().alphas_cumprod[499]) == pytest.approx(0.0785872429, rel=1e-9)


# ----------------------------------------------------------------------------- forward process


def test_add_noise_closed_form_per_sample_timesteps():
    s = NoiseScheduler()
    g = _gen(1)
    x0 = torch.randn(4, 6, 3, generator=g, dtype=F64)
    eps = torch.randn(4, 6, 3, generator=g, dtype=F64)
    t = torch.tensor([0, 1, 500, 999])
    x_t = s.add_noise(x0, eps, t)
    for b in range(4):
        a = float(s.alphas_cumprod[t[b]])
        assert torch.allclose(x_t[b], math.sqrt(a) * x0[b] + math.sqrt(1 - a) * eps[b])
    # a scalar t is the same level for the whole batch
    assert torch.allclose(s.add_noise(x0, eps, 500), s.add_noise(x0, eps, torch.full((4,), 500)))
    assert s.add_noise(x0.float(), eps.float(), t).dtype == torch.float32


def test_add_noise_empirical_mean_and_variance():
    s = NoiseScheduler()
    t, n = 300, 200_000
    x0 = torch.tensor([1.5, -0.7, 0.0], dtype=F64).expand(n, 3)
    eps = torch.randn(n, 3, generator=_gen(2), dtype=F64)
    x_t = s.add_noise(x0, eps, t)
    a = float(s.alphas_cumprod[t])
    assert torch.allclose(x_t.mean(0), math.sqrt(a) * x0[0], atol=0.01)       # 4.4 std errors
    assert torch.allclose(x_t.var(0), torch.full((3,), 1 - a, dtype=F64), rtol=0.015)


def test_predict_x0_inverts_add_noise():
    s = NoiseScheduler(beta_schedule="cosine")
    g = _gen(3)
    x0 = torch.randn(6, 40, 5, generator=g, dtype=F64)
    eps = torch.randn(6, 40, 5, generator=g, dtype=F64)
    t = torch.tensor([0, 7, 250, 600, 998, 999])
    x_t = s.add_noise(x0, eps, t)
    assert torch.allclose(s.predict_x0(x_t, eps, t), x0, atol=1e-9)            # Sketch2Anim Eq. (7)
    assert torch.allclose(s.predict_eps(x_t, x0, t), eps, atol=1e-9)


@pytest.mark.parametrize("kind", ["epsilon", "sample", "v_prediction"])
def test_training_target_is_consistent_with_the_steps(kind):
    """Whatever the network predicts, the true target sends a DDIM step to x0 exactly."""
    s = NoiseScheduler(prediction_type=kind)
    g = _gen(4)
    x0 = torch.randn(3, 8, generator=g, dtype=F64)
    eps = torch.randn(3, 8, generator=g, dtype=F64)
    t = torch.tensor([10, 400, 900])
    x_t = s.add_noise(x0, eps, t)
    target = s.training_target(x0, eps, t)
    expected = {"epsilon": eps, "sample": x0}.get(kind)
    if expected is not None:
        assert torch.equal(target, expected)
    out = s.ddim_step(target, t, torch.full((3,), -1), x_t)
    assert isinstance(out, StepOutput)
    assert torch.allclose(out.x0, x0, atol=1e-10)
    assert torch.allclose(out.x_prev, x0, atol=1e-10)


def test_sample_timesteps():
    s = NoiseScheduler(num_train_timesteps=50)
    t = s.sample_timesteps(10_000, generator=_gen(5))
    assert t.shape == (10_000,) and t.dtype == torch.int64
    assert int(t.min()) == 0 and int(t.max()) == 49
    assert torch.equal(t, s.sample_timesteps(10_000, generator=_gen(5)))      # reproducible


# ----------------------------------------------------------------------------- timesteps


def test_set_timesteps_spacings():
    s = NoiseScheduler()
    lead = s.set_timesteps(50)
    assert torch.equal(s.timesteps, lead) and s.num_inference_steps == 50
    assert lead.tolist() == list(range(980, -1, -20))
    trail = s.set_timesteps(50, spacing="trailing")
    assert trail.tolist() == list(range(999, 0, -20))
    lin = s.set_timesteps(50, spacing="linspace")
    assert lin[0] == 999 and lin[-1] == 0 and bool((lin[1:] < lin[:-1]).all())
    assert s.set_timesteps(1000).tolist() == list(range(999, -1, -1))
    assert NoiseScheduler(steps_offset=1).set_timesteps(50).tolist() == list(range(981, 0, -20))
    assert NoiseScheduler(timestep_spacing="trailing").set_timesteps(1).tolist() == [999]


# ----------------------------------------------------------------------------- DDIM


def test_ddim_step_matches_song_eq12_by_hand():
    s = NoiseScheduler()
    g = _gen(6)
    x_t = torch.randn(2, 5, generator=g, dtype=F64)
    eps = torch.randn(2, 5, generator=g, dtype=F64)
    z = torch.randn(2, 5, generator=g, dtype=F64)
    t, t_prev, eta = 500, 300, 0.3
    a, ap = float(s.alphas_cumprod[t]), float(s.alphas_cumprod[t_prev])
    x0 = (x_t - math.sqrt(1 - a) * eps) / math.sqrt(a)                            # Eq. (9)
    sigma = eta * math.sqrt((1 - ap) / (1 - a)) * math.sqrt(1 - a / ap)            # Eq. (16)
    x_prev = math.sqrt(ap) * x0 + math.sqrt(1 - ap - sigma ** 2) * eps + sigma * z  # Eq. (12)
    out = s.ddim_step(eps, t, t_prev, x_t, eta=eta, noise=z)
    assert torch.allclose(out.x0, x0, atol=1e-12)
    assert torch.allclose(out.x_prev, x_prev, atol=1e-12)
    assert float(s.ddim_sigma(t, t_prev)) * eta == pytest.approx(sigma, rel=1e-12)
    # η = 0 is deterministic and ignores the generator
    a0 = s.ddim_step(eps, t, t_prev, x_t, generator=_gen(0)).x_prev
    a1 = s.ddim_step(eps, t, t_prev, x_t, generator=_gen(1)).x_prev
    assert torch.equal(a0, a1)


def test_ddim_per_sample_timesteps_match_single_steps():
    s = NoiseScheduler()
    g = _gen(7)
    x_t = torch.randn(3, 4, 2, generator=g, dtype=F64)
    eps = torch.randn(3, 4, 2, generator=g, dtype=F64)
    t, tp = torch.tensor([999, 500, 20]), torch.tensor([979, 480, -1])
    batched = s.ddim_step(eps, t, tp, x_t).x_prev
    for b in range(3):
        single = s.ddim_step(eps[b:b + 1], int(t[b]), int(tp[b]), x_t[b:b + 1]).x_prev
        assert torch.allclose(batched[b:b + 1], single, atol=1e-13)


@pytest.mark.parametrize("steps,spacing", [(1, "trailing"), (50, "leading"), (50, "trailing"),
                                           (1000, "leading")])
def test_ddim_with_oracle_recovers_x0(steps, spacing):
    s = NoiseScheduler(timestep_spacing=spacing)
    g = _gen(8)
    x0 = torch.randn(2, 40, 7, generator=g, dtype=F64)
    eps = torch.randn(2, 40, 7, generator=g, dtype=F64)
    x_T = s.add_noise(x0, eps, int(s.set_timesteps(steps)[0]))
    seen = []
    out = s.sample(_oracle(s, x0), x0.shape, steps=steps, method="ddim", x_T=x_T,
                   callback=lambda i, t, x, x0_hat: seen.append((i, t, x0_hat)))
    assert torch.allclose(out, x0, atol=1e-8)
    assert [i for i, _, _ in seen] == list(range(steps))
    assert torch.allclose(seen[0][2], x0, atol=1e-8)        # x̂₀ is exact from the first step


# ----------------------------------------------------------------------------- DDPM


def test_ddpm_posterior_closed_form():
    s = NoiseScheduler()
    g = _gen(9)
    x0 = torch.randn(4, 3, generator=g, dtype=F64)
    x_t = torch.randn(4, 3, generator=g, dtype=F64)
    for t in (1, 10, 500, 999):
        ab, abp, beta = (float(s.alphas_cumprod[t]), float(s.alphas_cumprod[t - 1]),
                         float(s.betas[t]))
        mean, var = s.posterior(x0, x_t, t)
        mu = (math.sqrt(abp) * beta / (1 - ab) * x0
              + math.sqrt(1 - beta) * (1 - abp) / (1 - ab) * x_t)                 # DDPM Eq. (7)
        assert torch.allclose(mean, mu, atol=1e-12)
        assert float(var) == pytest.approx((1 - abp) / (1 - ab) * beta, rel=1e-10)  # β̃_t
    # last step: the posterior is x0 itself
    mean, var = s.posterior(x0, x_t, 0)
    assert torch.allclose(mean, x0, atol=1e-12) and float(var) == 0.0


def test_ddpm_step_samples_the_posterior():
    s = NoiseScheduler()
    n, t = 100_000, 400
    x_t = torch.full((n, 2), 0.8, dtype=F64)
    eps_hat = torch.tensor([0.3, -1.2], dtype=F64).expand(n, 2)
    out = s.ddpm_step(eps_hat, t, x_t, generator=_gen(10))
    mean, var = s.posterior(out.x0[:1], x_t[:1], t)
    assert torch.allclose(out.x0[0], s.predict_x0(x_t[:1], eps_hat[:1], t)[0])
    assert torch.allclose(out.x_prev.mean(0), mean[0], atol=4 * math.sqrt(float(var) / n))
    assert float(out.x_prev.var(0).mean()) == pytest.approx(float(var), rel=0.015)
    # at t = 0 the step is deterministic and returns x̂₀
    last = s.ddpm_step(eps_hat[:4], 0, x_t[:4], generator=_gen(11))
    assert torch.allclose(last.x_prev, last.x0, atol=1e-12)
    # "fixed_large" uses β_t as the variance
    z = torch.randn(4, 2, generator=_gen(12), dtype=F64)
    big = NoiseScheduler(variance_type="fixed_large")
    mu, _ = big.posterior(out.x0[:4], x_t[:4], t)
    step = big.ddpm_step(eps_hat[:4], t, x_t[:4], noise=z).x_prev
    assert torch.allclose(step, mu + math.sqrt(float(big.betas[t])) * z, atol=1e-12)


def test_ddim_eta1_on_consecutive_steps_is_ddpm():
    s = NoiseScheduler()
    g = _gen(13)
    x_t = torch.randn(3, 5, generator=g, dtype=F64)
    eps = torch.randn(3, 5, generator=g, dtype=F64)
    z = torch.randn(3, 5, generator=g, dtype=F64)
    for t in (1, 250, 999):
        ddim = s.ddim_step(eps, t, t - 1, x_t, eta=1.0, noise=z).x_prev
        ddpm = s.ddpm_step(eps, t, x_t, noise=z).x_prev
        assert torch.allclose(ddim, ddpm, atol=1e-10)


def test_clip_sample():
    s = NoiseScheduler(clip_sample=True, clip_sample_range=1.0)
    x_t = torch.tensor([[3.0, -0.2]], dtype=F64)
    eps = torch.zeros_like(x_t)
    out = s.ddim_step(eps, 10, -1, x_t)
    x0 = s.predict_x0(x_t, eps, 10)                         # unclipped (Eq. (7) only)
    assert float(x0[0, 0]) > 3.0
    assert torch.allclose(out.x0, x0.clamp(-1, 1))


# ----------------------------------------------------------------------------- sampling a Gaussian


MU, SIGMA, N = 2.0, 0.5, 20_000


def test_ddpm_1000_steps_samples_a_gaussian():
    s = NoiseScheduler()
    x = s.sample(_gaussian_eps(s, MU, SIGMA), (N, 1), method="ddpm", generator=_gen(14),
                 dtype=F64)
    # measured: mean 2.0035, std 0.4975. DDPM's β̃_t is the lower of the two reverse
    # variances of DDPM Sec. 3.2, so the std comes out slightly small (−0.5 … −0.7 %).
    assert float(x.mean()) == pytest.approx(MU, rel=0.01)
    assert float(x.std()) == pytest.approx(SIGMA, rel=0.02)


@pytest.mark.parametrize("spacing", ["leading", "trailing"])
def test_ddim_50_steps_samples_a_gaussian(spacing):
    s = NoiseScheduler(timestep_spacing=spacing)
    x_T = torch.randn(N, 1, generator=_gen(15), dtype=F64)
    x = s.sample(_gaussian_eps(s, MU, SIGMA), None, steps=50, method="ddim", x_T=x_T)
    assert float(x.mean()) == pytest.approx(MU, rel=0.01)
    # measured: mean 1.9971 / 1.9984, std 0.4709 / 0.4699 (leading / trailing); see below
    assert float(x.std()) == pytest.approx(SIGMA, rel=0.07)
    # For Gaussian data each η = 0 step is affine, x_prev − √ᾱ' μ = r (x_t − √ᾱ μ) with
    # r = (√(ᾱᾱ') σ² + √((1−ᾱ)(1−ᾱ'))) / (ᾱσ² + 1 − ᾱ) ≤ √(v'/v) (Cauchy–Schwarz): DDIM
    # shrinks the spread; here by 5.5 % / 5.7 % (leading / trailing; linear schedule, 50
    # steps, σ = 0.5), 0.3 % with 1000 steps.
    ts = s.set_timesteps(50).tolist() + [-1]
    ab = lambda t: 1.0 if t < 0 else float(s.alphas_cumprod[t])
    r = 1.0
    for t, tp in zip(ts[:-1], ts[1:]):
        a, ap = ab(t), ab(tp)
        r *= ((math.sqrt(a * ap) * SIGMA ** 2 + math.sqrt((1 - a) * (1 - ap)))
              / (a * SIGMA ** 2 + 1 - a))
    expected = MU + (x_T - math.sqrt(ab(ts[0])) * MU) * r
    assert torch.allclose(x, expected, atol=1e-10)
    assert r / SIGMA == pytest.approx({"leading": 0.9449, "trailing": 0.9428}[spacing], abs=2e-4)


# ----------------------------------------------------------------------------- guidance


def test_classifier_free_guidance():
    g = _gen(16)
    eu = torch.randn(2, 4, 3, generator=g)
    ec = torch.randn(2, 4, 3, generator=g)
    assert torch.equal(classifier_free_guidance(eu, ec, 0.0), eu)
    assert torch.equal(classifier_free_guidance(eu, ec, 1.0), ec)
    assert DEFAULT_GUIDANCE_SCALE == 7.5
    assert torch.allclose(classifier_free_guidance(eu, ec), eu + 7.5 * (ec - eu), atol=1e-5)
    w = torch.tensor([0.0, 1.0]).reshape(2, 1, 1)                        # one scale per sample
    mixed = classifier_free_guidance(eu, ec, w)
    assert torch.equal(mixed[0], eu[0]) and torch.equal(mixed[1], ec[1])
    with pytest.raises(ValueError, match="same shape"):
        classifier_free_guidance(eu, ec[:1])
    with pytest.raises(ValueError, match="finite"):
        classifier_free_guidance(eu, ec, float("nan"))


def test_sample_with_guidance_scale_0_and_1():
    s = NoiseScheduler()
    calls = []

    def model_fn(x, t, c):
        calls.append(c)
        assert t.shape == (x.shape[0],) and t.dtype == torch.int64
        return 0.1 * x + c                                 # c is a constant "condition" offset

    shape = (3, 4)
    kw = dict(steps=10, generator=None, dtype=F64)
    x_T = torch.randn(shape, generator=_gen(17), dtype=F64)
    cond_only = s.sample(model_fn, shape, cond=0.3, x_T=x_T, **kw)
    assert calls == [0.3] * 10
    uncond_only = s.sample(model_fn, shape, cond=-0.2, x_T=x_T, **kw)
    calls.clear()
    w1 = s.sample(model_fn, shape, guidance_scale=1.0, cond=0.3, uncond=-0.2, x_T=x_T, **kw)
    assert calls == [0.3, -0.2] * 10                       # two network calls per step
    w0 = s.sample(model_fn, shape, guidance_scale=0.0, cond=0.3, uncond=-0.2, x_T=x_T, **kw)
    assert torch.equal(w1, cond_only) and torch.equal(w0, uncond_only)


def test_sample_is_reproducible_and_shows_progress(capsys):
    s = NoiseScheduler(num_train_timesteps=100)
    model_fn = lambda x, t, c: 0.5 * x
    a = s.sample(model_fn, (2, 3), steps=5, method="ddim", eta=1.0, generator=_gen(18))
    b = s.sample(model_fn, (2, 3), steps=5, method="ddim", eta=1.0, generator=_gen(18),
                 progress=True)
    assert torch.equal(a, b) and a.shape == (2, 3) and a.dtype == torch.float32
    assert "ddim sampling" in capsys.readouterr().err
    c = s.sample(model_fn, (2, 3), method="ddpm", generator=_gen(18))      # default: T steps
    assert s.num_inference_steps == 100 and torch.isfinite(c).all()


# ----------------------------------------------------------------------------- config


def test_config_round_trip():
    s = NoiseScheduler(beta_schedule="scaled_linear", beta_start=0.00085, beta_end=0.012,
                       set_alpha_to_one=False, steps_offset=1, timestep_spacing="trailing")
    d = json.loads(json.dumps(s.to_dict()))                 # checkpoint-safe
    r = NoiseScheduler.from_dict(d)
    assert r.config == s.config and r.to_dict() == d
    assert torch.equal(r.alphas_cumprod, s.alphas_cumprod)
    assert NoiseScheduler.from_dict({}).config == SchedulerConfig()
    assert NoiseScheduler(SchedulerConfig(num_train_timesteps=10)).num_train_timesteps == 10
    with pytest.raises(ValueError, match="unknown scheduler config keys"):
        NoiseScheduler.from_dict({**d, "beta_max": 1.0})
    with pytest.raises(ValueError, match="either"):
        NoiseScheduler(SchedulerConfig(), beta_schedule="cosine")


def test_set_alpha_to_one_false_ends_at_alpha_bar_0():
    s = NoiseScheduler(set_alpha_to_one=False)
    x0 = torch.randn(2, 3, generator=_gen(19), dtype=F64)
    eps = torch.randn(2, 3, generator=_gen(20), dtype=F64)
    a0 = float(s.alphas_cumprod[0])
    out = s.ddim_step(eps, 20, -1, s.add_noise(x0, eps, 20))
    assert torch.allclose(out.x_prev, math.sqrt(a0) * x0 + math.sqrt(1 - a0) * eps, atol=1e-12)


# ----------------------------------------------------------------------------- errors


@pytest.mark.parametrize("kwargs,match", [
    (dict(num_train_timesteps=0), "num_train_timesteps"),
    (dict(num_train_timesteps=10.0), "num_train_timesteps"),
    (dict(beta_start=0.03, beta_end=0.02), "beta_start"),
    (dict(beta_schedule="quadratic"), "beta_schedule"),
    (dict(prediction_type="noise"), "prediction_type"),
    (dict(variance_type="learned"), "variance_type"),
    (dict(timestep_spacing="uniform"), "timestep_spacing"),
    (dict(clip_sample_range=0.0), "clip_sample_range"),
    (dict(steps_offset=-1), "steps_offset"),
])
def test_bad_config(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SchedulerConfig(**kwargs)


def test_bad_timesteps():
    s = NoiseScheduler()
    x = torch.zeros(2, 3)
    for bad, match in [(1000, r"\[0, 999\]"), (-1, r"\[0, 999\]"),
                       (torch.tensor([0, 1000]), r"\[0, 999\]"),
                       (3.0, "int"), (torch.tensor([1.0, 2.0]), "integer timesteps"),
                       (True, "integer"), (torch.zeros(2, 1, dtype=torch.long), "scalar or a"),
                       (torch.tensor([1, 2, 3]), "one timestep per sample")]:
        with pytest.raises(ValueError, match=match):
            s.add_noise(x, x, bad)
    with pytest.raises(ValueError, match="t_prev must be smaller"):
        s.ddim_step(x, 10, 10, x)
    with pytest.raises(ValueError, match=r"t_prev must lie in \[-1, 999\]"):
        s.ddim_step(x, 10, -2, x)
    with pytest.raises(ValueError, match="t_prev must be smaller"):
        s.posterior(x, x, 5, 7)


def test_bad_steps():
    s = NoiseScheduler(num_train_timesteps=100)
    with pytest.raises(ValueError, match="exceeds num_train_timesteps=100"):
        s.set_timesteps(101)
    with pytest.raises(ValueError, match=">= 1"):
        s.set_timesteps(0)
    with pytest.raises(ValueError, match="steps_offset"):
        NoiseScheduler(num_train_timesteps=100, steps_offset=1).set_timesteps(100)
    with pytest.raises(ValueError, match="exceeds"):
        s.sample(lambda x, t, c: x, (1, 2), steps=200)
    with pytest.raises(ValueError, match="method"):
        s.sample(lambda x, t, c: x, (1, 2), method="euler")
    with pytest.raises(ValueError, match="eta"):
        s.ddim_step(torch.zeros(1, 2), 5, 4, torch.zeros(1, 2), eta=-1.0)


def test_shape_mismatches_and_nan():
    s = NoiseScheduler()
    x = torch.zeros(2, 3)
    with pytest.raises(ValueError, match="x0 and noise must have the same shape"):
        s.add_noise(x, torch.zeros(2, 4), 5)
    with pytest.raises(ValueError, match="x_t and eps must have the same shape"):
        s.predict_x0(x, torch.zeros(3, 3), 5)
    with pytest.raises(ValueError, match="model_output and x_t"):
        s.ddim_step(torch.zeros(2, 4), 5, 4, x)
    with pytest.raises(ValueError, match="model_output and x_t"):
        s.ddpm_step(torch.zeros(1, 3), 5, x)
    nan = torch.tensor([[0.0, float("nan"), 1.0], [0, 0, 0]])
    with pytest.raises(ValueError, match="x0 contains NaN"):
        s.add_noise(nan, x, 5)
    with pytest.raises(ValueError, match="model_output contains NaN"):
        s.ddim_step(nan, 5, 4, x)
    with pytest.raises(ValueError, match="x_t contains NaN"):
        s.ddpm_step(x, 5, nan)
    with pytest.raises(ValueError, match="must return a tensor of shape"):
        s.sample(lambda x, t, c: x[:, :1], (2, 3), steps=2)
    with pytest.raises(ValueError, match="model_output contains NaN"):
        s.sample(lambda x, t, c: x * float("nan"), (2, 3), steps=2)
    with pytest.raises(ValueError, match="does not match x_T"):
        s.sample(lambda x, t, c: x, (2, 4), steps=2, x_T=x)
    with pytest.raises(ValueError, match="shape"):
        s.sample(lambda x, t, c: x, None, steps=2)


def test_import_physlab_motion_does_not_import_this_module():
    import subprocess
    import sys
    code = ("import sys, physlab.motion; "
            "assert 'physlab.motion.diffusion' not in sys.modules; "
            "assert 'torch' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
    assert np.isfinite(NoiseScheduler().betas.numpy()).all()


def test_full_ddpm_visits_every_timestep_despite_steps_offset():
    """MLD's schedule has steps_offset=1; a 1000-step DDPM run still goes 999 .. 0."""
    sch = NoiseScheduler(num_train_timesteps=20, steps_offset=1)
    seen = []
    sch.sample(lambda x, t, c: torch.zeros_like(x), (1, 3), method="ddpm",
               generator=torch.Generator().manual_seed(0),
               callback=lambda i, t, x, x0: seen.append(t))
    assert seen == list(range(19, -1, -1))


# ----------------------------------------------------------------------------- DDIM inversion


def _gaussian_x0(sched, mu, sigma):
    """The optimal x̂₀-predictor E[x0 | x_t] for data x0 ~ N(mu, sigma²)."""
    def model_fn(x_t, t, cond=None):
        a = _bcast(sched.alphas_cumprod[t], x_t)
        return mu + a.sqrt() * sigma ** 2 * (x_t - a.sqrt() * mu) / (a * sigma ** 2 + 1 - a)
    return model_fn


def test_ddim_invert_step_is_sketch2anim_eq17_by_hand():
    s = NoiseScheduler(set_alpha_to_one=True)
    g = _gen(3)
    x = torch.randn(2, 5, generator=g, dtype=F64)
    eps = torch.randn(2, 5, generator=g, dtype=F64)
    t, tp = 500, 480
    w_t, w_p = float(s.alphas_cumprod[t]), float(s.alphas_cumprod[tp])
    # Eq. (17): z_{t+1} = sqrt(w_{t+1}/w_t) z_t + (sqrt(1-w_{t+1}) - sqrt(w_{t+1}/w_t) sqrt(1-w_t)) eps
    want = (math.sqrt(w_t / w_p) * x
            + (math.sqrt(1 - w_t) - math.sqrt(w_t / w_p) * math.sqrt(1 - w_p)) * eps)
    got = s.ddim_invert_step(eps, t, tp, x)
    assert torch.allclose(got.x_prev, want, atol=1e-12)
    # one inversion step undone by one sampling step with the same ε̂ returns x exactly
    back = s.ddim_step(eps, t, tp, got.x_prev).x_prev
    assert torch.allclose(back, x, atol=1e-10)


@pytest.mark.parametrize("kind", ["epsilon", "sample"])
def test_ddim_inversion_then_sampling_returns_the_data(kind):
    """Gaussian data model (exact network): inverting then sampling reconstructs x0, with an
    error that falls as the number of steps grows (the ODE's discretisation error)."""
    mu, sigma = 0.3, 0.7
    g = _gen(11)
    x0 = mu + sigma * torch.randn(4, 40, 3, generator=g, dtype=F64)
    errs = []
    for steps in (10, 50, 250):
        s = NoiseScheduler(prediction_type=kind, timestep_spacing="trailing",
                           set_alpha_to_one=True)
        fn = (_gaussian_eps if kind == "epsilon" else _gaussian_x0)(s, mu, sigma)
        z = s.invert(fn, x0, steps=steps)
        assert z.std() > 0.8                          # it really is noise-like, not x0
        back = s.sample(fn, None, steps=steps, method="ddim", x_T=z)
        errs.append(float((back - x0).abs().max()))
    assert errs[2] < errs[1] < errs[0]
    assert errs[2] < 0.05 * float(x0.abs().max())


def test_ddim_inversion_errors():
    s = NoiseScheduler()
    x = torch.zeros(1, 4)
    with pytest.raises(ValueError, match="t_prev must be smaller"):
        s.ddim_invert_step(x, 10, 10, x)
    with pytest.raises(ValueError, match="model_fn must return"):
        s.invert(lambda x, t, c: x[:, :2], x, steps=5)
    with pytest.raises(ValueError, match="x0"):
        s.invert(lambda x, t, c: x, torch.full((1, 4), float("nan")), steps=5)
    with pytest.raises(ValueError, match="fixed_point"):
        s.invert(lambda x, t, c: x, x, steps=5, fixed_point=-1)


def test_ddim_inversion_with_mld_settings_and_the_scheduler_state():
    """The shipped schedule (MLD: scaled-linear, "leading" with offset 1, ᾱ_final = ᾱ_0): the
    first levels are nearly noise-free, so an x̂₀-network's ε̂ amplifies its errors; even an
    exact Gaussian model round-trips far worse than with "trailing" spacing (the numbers
    physlab.motion.blend quotes), ε-prediction better; fixed-point refinement diverges for
    x̂₀. invert() leaves the scheduler's timesteps as they were."""
    mu, sigma = 0.3, 0.7
    x0 = mu + sigma * torch.randn(4, 40, 3, generator=_gen(11), dtype=F64)
    mld = dict(beta_start=0.00085, beta_end=0.012, beta_schedule="scaled_linear",
               timestep_spacing="leading", steps_offset=1, set_alpha_to_one=False)
    err = {}
    for kind, fp in (("sample", 0), ("sample", 3), ("epsilon", 0)):
        s = NoiseScheduler(prediction_type=kind, **mld)
        fn = (_gaussian_eps if kind == "epsilon" else _gaussian_x0)(s, mu, sigma)
        s.set_timesteps(7)
        before = s.timesteps.clone()
        z = s.invert(fn, x0, steps=20, fixed_point=fp)
        assert torch.equal(s.timesteps, before) and s.num_inference_steps == 7
        back = s.sample(fn, None, steps=20, method="ddim", x_T=z)
        err[kind, fp] = float((back - x0).abs().max())
    assert 0.3 < err["sample", 0] < 1.0                   # measured 0.63
    assert err["epsilon", 0] < 0.5 * err["sample", 0]      # measured 0.12
    assert err["sample", 3] > 10 * err["sample", 0]        # diverges (measured 35)


def test_ddim_inversion_v_prediction_round_trip():
    mu, sigma = 0.0, 0.8
    x0 = sigma * torch.randn(2, 40, 3, generator=_gen(5), dtype=F64)
    s = NoiseScheduler(prediction_type="v_prediction", timestep_spacing="trailing",
                       set_alpha_to_one=True)
    eps_fn = _gaussian_eps(s, mu, sigma)

    def v_fn(x_t, t, cond=None):                  # v = √ᾱ ε − √(1−ᾱ) x̂₀ of the exact model
        a = _bcast(s.alphas_cumprod[t], x_t)
        eps = eps_fn(x_t, t)
        x0_hat = (x_t - (1 - a).sqrt() * eps) / a.sqrt()
        return a.sqrt() * eps - (1 - a).sqrt() * x0_hat

    errs = [float((s.sample(v_fn, None, steps=k, method="ddim", x_T=s.invert(v_fn, x0, steps=k))
                   - x0).abs().max()) for k in (20, 200)]
    assert errs[1] < errs[0] < 0.5
