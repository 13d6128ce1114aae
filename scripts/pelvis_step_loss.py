"""The text base trained with an extra pelvis-step loss in metres (docs/motion_experiments.md,
"Tried, not kept: a pelvis-step loss in metres").

``LAMBDA · mean(((Δp̂ − Δp) / 1 cm)²)`` over the pelvis columns of x̂₀ (the ``"absolute"``
features' first three; Δ = frame-to-frame step) is added to MDM's velocity loss
(:func:`physlab.motion.train.velocity_loss`, which train weights by ``--lambda-vel``), then
``physlab.motion.train`` runs with the remaining arguments. The feature scale of the pelvis
comes from the checkpoint's statistics, read before training from ``--scale-from``::

    python scripts/pelvis_step_loss.py 3 --scale-from data/motion/sketch2anim_control.pt \
        --num-threads 2 --stage base --steps 10000 --skip --no-skip-pelvis --snr-cap 10 \
        --balance 0.5 --lambda-vel 4 --style-drop 0.3 --out runs/pelvis_step.pt

``--levels LO HI`` (right after LAMBDA: ``pelvis_step_loss.py 0.05 --levels 0.5 1
--scale-from …``) keeps the term only for the windows noised to a level ``LO·T ≤ t < HI·T``
(T = the scheduler's number of levels; default 0 1, every window), to ask at which noise levels
the near-still pelvis's slow lean is settled. The level of each window is read from the call of
:func:`physlab.motion.train.recon_loss` that precedes the velocity loss in every base step.

(The feature statistics of a run on the same clips equal the shipped checkpoint's.)
"""
from __future__ import annotations

import sys


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    lo, hi = 0.0, 1.0
    if len(argv) > 3 and argv[1] == "--levels":
        lo, hi = float(argv[2]), float(argv[3])
        del argv[1:4]
    if len(argv) < 3 or argv[1] != "--scale-from" or "--lambda-vel" not in argv:
        raise SystemExit(__doc__)
    import torch

    import physlab.motion.train as train
    from physlab.motion.checkpoint import load_checkpoint

    lam = float(argv[0])
    lam_vel = float(argv[argv.index("--lambda-vel") + 1])
    if lam < 0 or lam_vel <= 0 or not 0 <= lo < hi <= 1:
        raise SystemExit(f"need LAMBDA >= 0, --lambda-vel > 0 and 0 <= LO < HI <= 1 "
                         f"(--levels), got {lam}, {lam_vel}, {lo} {hi}")
    stats = load_checkpoint(argv[2])["feature_stats"]
    scale = torch.as_tensor(stats["std"][:3], dtype=torch.float32) / 0.01    # 1 cm units
    plain, plain_recon = train.velocity_loss, train.recon_loss
    level = {}

    def recon_loss(out, target, t, scheduler, snr_cap=0.0, weights=None):
        n = len(scheduler.alphas_cumprod)
        level["keep"] = ((t >= lo * n) & (t < hi * n)).float()                       # (B,)
        return plain_recon(out, target, t, scheduler, snr_cap, weights)

    def velocity_loss(x0_hat, x0, weights=None):
        d = (x0_hat[:, 1:, :3] - x0_hat[:, :-1, :3]) - (x0[:, 1:, :3] - x0[:, :-1, :3])
        per_window = ((d * scale.to(d.dtype)) ** 2).mean(dim=(1, 2))               # (B,)
        keep = level.get("keep", torch.ones_like(per_window)).to(per_window.dtype)
        return plain(x0_hat, x0, weights) + (lam / lam_vel) * (keep * per_window).mean()

    train.velocity_loss = velocity_loss        # train.main looks both up in its own module
    train.recon_loss = recon_loss
    train.main(argv[3:])


if __name__ == "__main__":
    main()
