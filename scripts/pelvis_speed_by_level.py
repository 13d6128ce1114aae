"""At which noise level does a text-only clip's pelvis start to sway? (docs/motion_experiments.md,
"Why the near-still actions miss their speed bound").

Samples ``--seeds`` text-only clips of one action text with the generator's defaults and
decodes the clean estimate x̂₀ of every DDIM step (``NoiseScheduler.ddim_step``'s second
output, recorded on the way); prints, per level t, the mean horizontal pelvis speed (m/s) and
forward travel (m) of those estimates over the seeds, next to the real clips of that action
(``../shared/data``; skipped without it)::

    python scripts/pelvis_speed_by_level.py data/motion/sketch2anim_control.pt \
        "a person waves the right hand" --seeds 16

The x̂₀ of a step is decoded without the body constraints (:meth:`Generator._decode`), the way
the sampler hands it to the next step; the last row is the returned clip before them.
"""
from __future__ import annotations

import argparse

import numpy as np


def pelvis_speed(joints, fps=20.0):
    """Mean horizontal pelvis speed (m/s) and forward travel (m) of ``(N, 22, 3)`` joints:
    the ``speed_m_s`` and ``forward_m`` columns of
    :func:`physlab.motion.evaluate.motion_statistics`."""
    from physlab.motion.evaluate import STATISTICS, motion_statistics

    s = dict(zip(STATISTICS, motion_statistics(joints, fps=fps)[0]))
    return float(s["speed_m_s"]), float(s["forward_m"])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoint")
    ap.add_argument("text", nargs="?", default="a person waves the right hand")
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--num-threads", type=int, default=2)
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error(f"--seeds must be >= 1, got {args.seeds}")
    import torch

    from physlab.motion.sampling import Generator

    torch.set_num_threads(args.num_threads)
    gen = Generator.from_checkpoint(args.checkpoint)
    recorded, plain = [], gen.scheduler.ddim_step

    def ddim_step(out, t, t_prev, x):
        x_new, x0 = plain(out, t, t_prev, x)
        recorded.append((int(t), x0.detach().clone()))
        return x_new, x0

    gen.scheduler.ddim_step = ddim_step          # this instance only
    by_level = {}
    for seed in range(args.seeds):
        recorded.clear()
        gen(args.text, seed=seed)
        with gen._using_text_model(True):         # a text model decodes with its statistics
            for t, x0 in recorded:
                by_level.setdefault(t, []).append(pelvis_speed(gen._decode(x0)[1]))
    print(f"{args.text!r}, {args.seeds} seeds, {args.checkpoint}")
    print("| level t | pelvis speed of x̂₀ (m/s) | forward travel (m) |\n|---|---|---|")
    for t in sorted(by_level, reverse=True):
        speed, forward = np.mean(by_level[t], axis=0)
        print(f"| {t} | {speed:.3f} | {forward:+.3f} |")
    from physlab.motion.dataset import ACTION_PHRASES, action_text, load_clips, make_windows

    content = next((c for c in ACTION_PHRASES if action_text(c) == args.text), None)
    try:
        win = make_windows(load_clips(contents=[content]), length=40, stride=10) if content \
            else None
    except (OSError, ValueError):           # no ../shared/data: no real row
        win = None
    if win is not None and len(win.joints):
        from physlab.motion.evaluate import STATISTICS, motion_statistics

        stats = motion_statistics(win.joints, fps=win.fps)
        speed = stats[:, STATISTICS.index("speed_m_s")].mean()
        print(f"| real ({len(win.joints)} windows) | {speed:.3f} | |")


if __name__ == "__main__":
    main()
