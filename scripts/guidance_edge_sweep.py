"""Guided clips on the 64 held-out windows (Cross protocol) under several condition-edge hinges.

Issue 12 bounds the step where a partial trajectory starts or ends at 3x the clip's median
step; the x̂₀ guidance carries a hinge on it (``physlab.motion.sampling.GUIDANCE_EDGES``
λ_e, ``EDGE_STEP`` c_e). This prints, per ``λ_e,c_e`` pair, the worst and count of clips over
2.5 and 3 (``metrics.boundary_step_ratio``), the worst ``boundary_jump_ratio``, and the guided
errors, so the trade-off can be re-measured (``docs/motion_experiments.md``, "No jump where a
stroke ends")::

    python scripts/guidance_edge_sweep.py [--control CKPT] [--seed S] 10,2.5 100,2.5 1000,2.5
"""
from __future__ import annotations

import argparse

import numpy as np


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("specs", nargs="+", help="λ_e,c_e pairs, e.g. 10,2.5")
    p.add_argument("--control", default="data/motion/sketch2anim_control.pt")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--windows", type=int, default=64)
    args = p.parse_args(argv)
    specs = []
    for spec in args.specs:
        try:
            lam, cap = (float(v) for v in spec.split(","))
        except ValueError:
            p.error(f"a spec is 'λ_e,c_e' (two numbers), got {spec!r}")
        specs.append((lam, cap))

    import torch

    import physlab.motion.sampling as S
    from physlab.motion.evaluate import (GUIDED, _sample, clip_metrics, eval_conditions,
                                         held_out_windows)
    from physlab.motion.metrics import boundary_jump_ratio, boundary_step_ratio

    torch.set_num_threads(1)
    data = held_out_windows(args.windows)
    conds = eval_conditions(data["joints"], seed=args.seed)
    gen = S.Generator.from_checkpoint(args.control)
    saved = S.GUIDANCE_EDGES, S.EDGE_STEP
    try:
        for lam, cap in specs:
            S.GUIDANCE_EDGES, S.EDGE_STEP = lam, cap
            x, sec = _sample(gen, data, conds, True, steps=50, guidance=S.CONTROL_TEXT_GUIDANCE,
                             seed=args.seed, progress=False, label="guided", options=GUIDED)
            r = np.array([boundary_step_ratio(m, c.mask) for m, c in zip(x, conds)])
            jump = np.nanmax([boundary_jump_ratio(m, c.mask) for m, c in zip(x, conds)])
            m = clip_metrics(x, conds, sec)
            print(f"λ_e {lam:g}, c_e {cap:g}: edge step ratio max {np.nanmax(r):.2f} "
                  f"(> 2.5: {int(np.sum(r > 2.5))}, > 3: {int(np.sum(r > 3))} of "
                  f"{int(np.sum(np.isfinite(r)))}), edge jump max {jump:.2f}; "
                  f"traj. {m['trajectory_error_3d']:.4f} m, keypose {m['keypose_mpjpe_3d']:.4f} m, "
                  f"AUJ {m['auj']:.3f}, skating {m['foot_skating']:.3f}, {sec:.2f} s/clip",
                  flush=True)
    finally:
        S.GUIDANCE_EDGES, S.EDGE_STEP = saved


if __name__ == "__main__":
    main()
