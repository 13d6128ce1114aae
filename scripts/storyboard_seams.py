"""Seam readings of the example storyboard (README, "Seams") for several seeds and joins.

Animates ``data/motion/example_storyboard.json`` (drawn walk, bow, wave) with each join method
and seed and prints, per junction, the largest joint acceleration over the join over the
clips' largest near it (``blend.junction_acceleration_ratio``), the largest step over the
clips' largest near it (``junction_step_ratio(..., "local")``), and the whole animation's
worst bone-length std (m) and share of frames with a foot below the floor::

    python scripts/storyboard_seams.py [--control CKPT] [--seeds 4] [inversion concat linear]
"""
from __future__ import annotations

import argparse
from pathlib import Path

BOARD = Path(__file__).resolve().parents[1] / "data" / "motion" / "example_storyboard.json"


def main(argv=None):
    from physlab.motion.blend import BLEND_METHODS

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("methods", nargs="*", default=["inversion", "concat", "linear"],
                   help=f"join methods (default: inversion concat linear; any of "
                        f"{', '.join(BLEND_METHODS)})")
    p.add_argument("--control", default=None, help="generator checkpoint (default: shipped)")
    p.add_argument("--seeds", type=int, default=4, help="seeds 0 .. N-1 (default 4)")
    args = p.parse_args(argv)
    bad = [m for m in args.methods if m not in BLEND_METHODS]
    if bad:
        p.error(f"unknown join method {bad[0]!r}; choose from {', '.join(BLEND_METHODS)}")
    if args.seeds < 1:
        p.error(f"--seeds must be >= 1, got {args.seeds}")

    import torch

    from physlab.motion.blend import junction_acceleration_ratio, junction_step_ratio
    from physlab.motion.metrics import bone_length_variation, floor_penetration
    from physlab.motion.storyboard import Storyboard, animate_storyboard

    torch.set_num_threads(1)
    board = Storyboard.load(BOARD)
    print("method seed | acceleration ratio per junction | local step ratio per junction | "
          "bone std (m) | floor share")
    for method in args.methods:
        for seed in range(args.seeds):
            a = animate_storyboard(board, seed=seed, method=method, checkpoint=args.control)
            pairs = [(a.windows[k], a.clips[k:k + 2]) for k in range(len(a.windows))]
            acc = [junction_acceleration_ratio(a.joints, w, c) for w, c in pairs]
            step = [junction_step_ratio(a.joints, w, c, "local") for w, c in pairs]
            print(f"{method} {seed} | {' '.join(f'{v:.2f}' for v in acc)} | "
                  f"{' '.join(f'{v:.2f}' for v in step)} | "
                  f"{bone_length_variation(a.joints):.5f} | {floor_penetration(a.joints):.4f}",
                  flush=True)


if __name__ == "__main__":
    main()
