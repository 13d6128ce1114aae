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

(The feature statistics of a run on the same clips equal the shipped checkpoint's.)
"""
from __future__ import annotations

import sys


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) < 3 or argv[1] != "--scale-from" or "--lambda-vel" not in argv:
        raise SystemExit(__doc__)
    import torch

    import physlab.motion.train as train
    from physlab.motion.checkpoint import load_checkpoint

    lam = float(argv[0])
    lam_vel = float(argv[argv.index("--lambda-vel") + 1])
    if lam < 0 or lam_vel <= 0:
        raise SystemExit(f"need LAMBDA >= 0 and --lambda-vel > 0, got {lam}, {lam_vel}")
    stats = load_checkpoint(argv[2])["feature_stats"]
    scale = torch.as_tensor(stats["std"][:3], dtype=torch.float32) / 0.01    # 1 cm units
    plain = train.velocity_loss

    def velocity_loss(x0_hat, x0):
        d = (x0_hat[:, 1:, :3] - x0_hat[:, :-1, :3]) - (x0[:, 1:, :3] - x0[:, :-1, :3])
        return plain(x0_hat, x0) + (lam / lam_vel) * ((d * scale.to(d.dtype)) ** 2).mean()

    train.velocity_loss = velocity_loss        # train.main looks it up in its own module
    train.main(argv[3:])


if __name__ == "__main__":
    main()
