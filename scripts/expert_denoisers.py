"""Expert denoisers by noise level, text only: base HI samples the DDIM steps at t > T_S, base LO
the steps at t <= T_S (eDiff-I's idea; docs/motion_experiments.md, "A separate text model").

For each T_S it prints the held-out table's text-only jerk and skating against the real clips
(64 windows of take 002, ``physlab.motion.evaluate``) and the text adherence
(``evaluate --adherence``). HI and LO may be base or control checkpoints (a control
checkpoint's frozen base is used); both must share the features and noise schedule::

    python scripts/expert_denoisers.py runs/text_base.pt data/motion/sketch2anim_control.pt 20 100 300

T_S = -1 is HI alone, T_S = 999 LO alone.
"""
from __future__ import annotations

import argparse


def switched_generator(hi, lo, t_switch):
    """A text-only :class:`~physlab.motion.sampling.Generator` (HI's statistics, scheduler and
    text cache) whose denoiser is HI's for t > ``t_switch`` and LO's below."""
    import torch

    from physlab.motion.sampling import Generator

    class Switch(torch.nn.Module):
        def __init__(self, a, b):
            super().__init__()
            self.hi, self.lo, self.config = a, b, a.config

        def forward(self, x, t, text, drop):
            return (self.hi if int(t[0]) > t_switch else self.lo)(x, t, text, drop)

        def __getattr__(self, name):                  # the sampler's low-pass settings
            if name in ("low_pass", "column_low_pass"):
                return getattr(self.hi, name)
            return super().__getattr__(name)

        def __setattr__(self, name, value):
            if name in ("low_pass", "column_low_pass"):
                setattr(self.hi, name, value)
                setattr(self.lo, name, value)
                return
            super().__setattr__(name, value)

    g_hi, g_lo = Generator.from_checkpoint(hi), Generator.from_checkpoint(lo)
    if not torch.allclose(g_hi.scheduler.alphas_cumprod, g_lo.scheduler.alphas_cumprod) or \
            g_hi.config.feature_dim != g_lo.config.feature_dim:
        raise ValueError(f"{hi} and {lo} have different noise schedules or features")
    switch = Switch(g_hi.denoiser, g_lo.denoiser).eval()
    return Generator(switch, g_hi.scheduler, g_hi.stats, g_hi.text_cache, "base", hi)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("hi", help="checkpoint for the noisy steps (t > T_S)")
    p.add_argument("lo", help="checkpoint for the clean steps (t <= T_S)")
    p.add_argument("t_switch", nargs="+", type=int, help="T_S values, -1..999")
    p.add_argument("--windows", type=int, default=64)
    p.add_argument("--seeds", type=int, default=32, help="clips per action text (adherence)")
    p.add_argument("--steps", type=int, default=25)
    args = p.parse_args(argv)
    bad = [t for t in args.t_switch if not -1 <= t <= 999]
    if bad:
        p.error(f"T_S must be in -1..999, got {bad}")
    if args.windows < 1 or args.seeds < 1 or args.steps < 1:
        p.error("--windows, --seeds and --steps must be >= 1")

    import torch

    from physlab.motion import evaluate as E

    torch.set_num_threads(1)
    data = E.held_out_windows(args.windows)
    conds = E.eval_conditions(data["joints"], seed=0)
    real = E.clip_metrics(data["joints"], conds)
    for ts in args.t_switch:
        gen = switched_generator(args.hi, args.lo, ts)
        x, _ = E._sample(gen, data, conds, False, steps=args.steps, guidance=2.5, seed=0,
                         progress=False, label="text only")
        m = E.clip_metrics(x, conds)
        print(f"T_S = {ts}: held-out text only, against real: AUJ {m['auj'] / real['auj']:.2f}x, "
              f"PJ {m['pj'] / real['pj']:.2f}x, skating "
              f"{m['foot_skating'] / real['foot_skating']:.2f}x")
        original = E._load
        E._load = lambda *a, **k: gen                 # text_adherence loads by path
        try:
            res = E.text_adherence(args.hi, seeds=args.seeds, steps=args.steps, progress=False)
        finally:
            E._load = original
        print(E.format_adherence(res))
        print()


if __name__ == "__main__":
    main()
