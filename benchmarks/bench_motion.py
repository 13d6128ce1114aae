"""Benchmark: the Sketch2Anim-style motion generator on this CPU — sampling and training speed.

Run it with ``make bench`` (all benchmarks) or on its own::

    .venv/bin/python benchmarks/bench_motion.py            # full-size model, ~2 min
    .venv/bin/python benchmarks/bench_motion.py --quick    # smoke-size model, for the tests

It prints a table and never asserts on time. Needs the Bandai-Namco clips of
``../shared/data`` (training reads them); exits with a message when they are missing.

What is measured
----------------
1. **Training throughput** (windows per second, excluding the first step): a short run of
   :func:`physlab.motion.train.train` for stage ``base`` (text-conditioned denoiser) and
   stage ``control`` (trajectory ControlNet + keypose adapter on the frozen base), with the
   default model size (``DenoiserConfig``) and batch, one process with ``--threads`` threads
   (2; ``torchrun`` with two 1-thread processes is not faster on this machine); both again
   ``--repeats`` times with ``precision="auto"`` (bf16, forward passes in bfloat16 autocast,
   where the CPU has native bfloat16, :func:`~physlab.motion.train.native_bf16`; else fp32),
   and, interleaved with those, the same runs with ``torch.nn.Dropout`` in place of physlab's
   cheaper :class:`~physlab.motion.model.Dropout` (the reference), medians compared. The bf16
   rows are a ratio to float32; on a CPU without native bfloat16 they come from one run of
   at most 3 steps per stage, since emulated bfloat16 is 10-30x slower.
   The weights are whatever these few steps give — sampling speed does not depend on them.
2. **Sampling** with the shipped generator (``--checkpoint``, default
   :data:`~physlab.motion.sampling.DEFAULT_CHECKPOINT`; the trained weights matter, since
   the guidance's L-BFGS stops when it has converged; ``--quick`` samples the smoke model):
   one 40-frame clip with classifier-free guidance (two network passes per step, batched) and
   ``generate``'s default DDIM steps (25) on ``--sample-threads`` threads (1: with a batch of 2 the second thread costs
   more than it gives), median of ``--repeats`` runs: text only; keypose + trajectories by
   the networks alone (no inference guidance); with the default guidance of ``generate``
   (40 L-BFGS iterations on the last x̂₀); and the per-step guidance variants of Table A3
   (4 iterations per step through the network, first-order or L-BFGS;
   :data:`physlab.motion.evaluate.GUIDANCE_VARIANTS`).
   References, measured in the same run: the networks-only clip with the DDPM sampler over
   all training timesteps (999 with the MLD scheduler's ``steps_offset = 1``), and with the
   controlled network's encoders run one after the other (``Generator.fused = False``)
   instead of the blocks of one depth batched (:class:`~physlab.motion.model.
   FusedControlledDenoiser`).
   The paper reports 0.427 s per clip on an RTX 4090, guidance included (printed for
   orientation). Target (issue 12): a guided clip in at most 0.5 s on one thread. Then a
   3-frame storyboard (generation and two blends; target 5 s) and the sketch-overlay frames
   of its animation (:func:`physlab.viz.storyboard_view.sketch_overlay_frames`; target 5 s).
3. **Peak memory**: the process's maximum resident set size, and the checkpoint sizes.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np

PAPER_SECONDS_PER_CLIP = 0.427   # Sketch2Anim, RTX 4090, with guidance
TARGET_SECONDS_PER_CLIP = 0.5
#: Issue 14: seconds for a 3-frame storyboard (generation + 2 blends) on one thread.
TARGET_SECONDS_PER_STORYBOARD = 5.0
#: Drawing the sketch-overlay frames of that storyboard (every frame, 320² px).
TARGET_SECONDS_OVERLAY = 5.0


def _parser():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--train-steps", type=int, default=20)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=2, help="torch threads for training")
    p.add_argument("--sample-threads", type=int, default=1,
                   help="torch threads for sampling (batch-2 matmuls: 1 thread is fastest here)")
    p.add_argument("--checkpoint", default=None,
                   help="control checkpoint to sample from (default: the shipped one)")
    p.add_argument("--quick", action="store_true",
                   help="smoke-size model, 2 training steps, sampled instead of the shipped one")
    return p


@contextmanager
def _torch_dropout():
    """Build models with ``torch.nn.Dropout`` (the reference) instead of physlab's."""
    import torch

    from physlab.motion import model

    ours, model.Dropout = model.Dropout, torch.nn.Dropout
    try:
        yield
    finally:
        model.Dropout = ours


def _time(fn, repeats):
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        fn()
        times.append(time.perf_counter() - tic)
    return float(np.median(times))


def main(argv=None):
    args = _parser().parse_args(argv)
    import torch

    from physlab.datasets import external_data_dir
    from physlab.motion.evaluate import GUIDANCE_VARIANTS, GUIDED, UNGUIDED
    from physlab.motion.sampling import DEFAULT_CHECKPOINT, Generator
    from physlab.motion.train import native_bf16, train

    if external_data_dir() is None:
        print("bench_motion: the Bandai-Namco clips (../shared/data) are needed for training; "
              "skipped")
        return {"skipped": True}
    common = dict(progress=False, num_threads=args.threads)
    if args.quick:
        common.update(smoke=True, steps=2)
    else:
        common.update(steps=args.train_steps)
    out = {}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        base = train(stage="base", out=str(d / "base.pt"), **common)
        control = train(stage="control", base_ckpt=str(base["path"]), out=str(d / "control.pt"),
                        **common)

        def both_stages(tag, precision, **kw):    # a base run and a control run on `base`
            return {"base": train(stage="base", out=str(d / f"b{tag}.pt"), precision=precision,
                                  **kw),
                    "control": train(stage="control", base_ckpt=str(base["path"]),
                                     out=str(d / f"c{tag}.pt"), precision=precision, **kw)}

        native = native_bf16()
        prec = "bf16" if native else "fp32"   # what --precision auto resolves to on this CPU
        first, dropout = None, {}         # windows/s with physlab's / torch's dropout
        for r in range(1 if args.quick else args.repeats):
            for ref in (False, True):
                with _torch_dropout() if ref else nullcontext():
                    runs = both_stages(f"{r}{ref}", "auto", **common)
                first = first or runs                      # the first run with physlab's
                for k, v in runs.items():
                    dropout.setdefault((k, ref), []).append(v["windows_per_s"])
        # bf16 runs: the auto runs above where bf16 is native; else one short emulated run
        bf16 = (first if native else
                both_stages("_bf16", "bf16", **{**common, "steps": min(common["steps"], 3)}))
        dropout = {k: float(np.median(v)) for k, v in dropout.items()}
        sizes = {k: Path(r["path"]).stat().st_size / 2**20 for k, r in
                 (("base", base), ("control", control))}
        torch.set_num_threads(args.sample_threads)
        path = control["path"] if args.quick else (args.checkpoint or DEFAULT_CHECKPOINT)
        gen = Generator.from_checkpoint(path)
        text = gen.text_cache.texts[0]
        from physlab.demos.motion_diffusion import walk_window
        w, _ = walk_window()                     # a real walk (shipped), (40, 22, 3) m
        keypose, traj = w[-1], {"pelvis": w[20:, 0], "left_wrist": w[20:, 20]}
        from physlab.motion.sampling import DEFAULT_STEPS

        steps = 2 if args.quick else DEFAULT_STEPS          # generate's default (25)
        cfg = gen.scheduler.config   # every training timestep the spacing allows (999 with MLD's offset)
        ddpm_steps = 4 if args.quick else cfg.num_train_timesteps - cfg.steps_offset
        ctrl = dict(keypose_3d=keypose, keypose_at="last", trajectories_3d=traj, steps=steps)
        t_text = _time(lambda: gen(text, steps=steps), args.repeats)
        t_ctrl = _time(lambda: gen(text, **ctrl, **UNGUIDED), args.repeats)
        gen.fused = False                 # reference: the encoders one after the other
        t_unfused = _time(lambda: gen(text, **ctrl, **UNGUIDED), args.repeats)
        gen.fused = True
        t_guided = _time(lambda: gen(text, **ctrl, **GUIDED), args.repeats)
        t_variants = {k: _time(lambda: gen(text, **ctrl, **v), 1)
                      for k, v in GUIDANCE_VARIANTS.items()}
        t_ref = _time(lambda: gen(text, **{**ctrl, "steps": ddpm_steps}, method="ddpm",
                                  **UNGUIDED), 1)
        t_sketch = {}
        if gen.has_sketch_encoders:        # the same condition drawn in a 3/4 view (Sec. 5-6)
            from physlab.motion.camera import Camera

            cam = Camera(1.0, 15.0, 30.0)
            drawn = dict(keypose_2d=cam.project(keypose), keypose_at="last", camera=cam,
                         trajectories_2d={k: cam.project(v) for k, v in traj.items()},
                         steps=steps)
            t_sketch = {"networks only": _time(lambda: gen(text, **drawn, **UNGUIDED),
                                               args.repeats),
                        "+ 2D guidance (generate's default)": _time(
                            lambda: gen(text, **drawn, **GUIDED), args.repeats)}
        # a 3-frame storyboard (issue 14): three clips (guided where conditioned) + 2 blends
        from physlab.motion.features import canonicalize
        from physlab.motion.sampling import load_generator
        from physlab.motion.storyboard import Storyboard, StoryboardFrame, animate_storyboard

        first = canonicalize(w[-1:], ground=False)[0]      # the end pose as a first keypose
        board = Storyboard([StoryboardFrame(text, keypose_3d=keypose, keypose_at="last",
                                            trajectories_3d=traj),
                            StoryboardFrame(text), StoryboardFrame(text, keypose_3d=first)])
        load_generator(path)                   # animate_storyboard's cache: loaded, not timed
        t_board = {m: _time(lambda: animate_storyboard(board, checkpoint=path, steps=steps,
                                                       method=m), args.repeats)
                   for m in ("inversion", "linear")}
        from physlab.viz.storyboard_view import sketch_overlay_frames

        anim = animate_storyboard(board, checkpoint=path, steps=steps, method="linear")
        t_overlay = _time(lambda: sketch_overlay_frames(board, anim), args.repeats)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB -> MiB on Linux
    print(f"motion generator: training on {args.threads} thread(s), sampling on "
          f"{args.sample_threads}; model d_model={gen.config.d_model}, {gen.config.n_layers} blocks")
    print("what | value")
    print("--- | ---")
    print(f"parameters base / control (trainable) | {base['n_params']:,} / "
          f"{control['n_params']:,} ({control['n_trainable']:,})")
    print(f"training, base stage | {base['windows_per_s']:.0f} windows/s")
    print(f"training, control stage | {control['windows_per_s']:.0f} windows/s")
    how = "native" if native else "emulated: no native bfloat16 on this CPU, one short run"
    for k, ref in (("base", base), ("control", control)):
        wps = dropout[(k, False)] if native else bf16[k]["windows_per_s"]   # native: median
        print(f"training, {k} stage, --precision bf16 ({how}) | {wps:.0f} windows/s "
              f"({wps / ref['windows_per_s']:.2f}x float32)")
    for k in ("base", "control"):
        ours, ref = dropout[(k, False)], dropout[(k, True)]
        print(f"training, {k} stage, {prec}, physlab Dropout / torch.nn.Dropout (median of "
              f"{1 if args.quick else args.repeats}) | {ours:.0f} / {ref:.0f} windows/s "
              f"({ours / ref:.2f}x)")
    print(f"sampling from | {Path(path).name}")
    print(f"clip, text only, CFG, DDIM {steps} | {t_text:.3f} s")
    print(f"clip, keypose + trajectory, networks only, DDIM {steps} | {t_ctrl:.3f} s")
    print(f"reference: the same, encoders one after the other (Generator.fused = False) | "
          f"{t_unfused:.3f} s (fused / sequential = {t_ctrl / t_unfused:.2f})")
    print(f"clip, keypose + trajectory + guidance (generate's default) | {t_guided:.3f} s")
    for k, t in t_variants.items():
        print(f"clip, keypose + trajectory {k} (1 run) | {t:.3f} s")
    for k, t in t_sketch.items():
        print(f"clip, 2D sketch (2D encoders), {k} | {t:.3f} s (paper: "
              f"{PAPER_SECONDS_PER_CLIP} s on an RTX 4090)")
    print(f"reference: networks-only clip, DDPM {ddpm_steps} | {t_ref:.3f} s (DDIM/DDPM = "
          f"{t_ctrl / t_ref:.3f})")
    for m, t in t_board.items():
        print(f"3-frame storyboard, generation + 2 {m} blends (median of {args.repeats}) | "
              f"{t:.3f} s (target <= {TARGET_SECONDS_PER_STORYBOARD} s)")
    print(f"sketch-overlay frames of that storyboard's {len(anim.joints)} frames "
          f"(physlab.viz.storyboard_view) | {t_overlay:.3f} s (target < "
          f"{TARGET_SECONDS_OVERLAY} s)")
    print(f"checkpoints base / control (resumable, with optimizer) | {sizes['base']:.1f} / "
          f"{sizes['control']:.1f} MiB")
    print(f"peak resident memory | {peak:.0f} MiB")
    verdict = "met" if t_guided <= TARGET_SECONDS_PER_CLIP else "NOT met"
    print(f"\ntarget <= {TARGET_SECONDS_PER_CLIP} s per guided clip on {args.sample_threads} "
          f"thread(s): {verdict}; paper: {PAPER_SECONDS_PER_CLIP} s on an RTX 4090 → ratio "
          f"{t_guided / PAPER_SECONDS_PER_CLIP:.2f}")
    out.update(base=base, control=control, bf16=bf16, seconds_text=t_text,
               seconds_control=t_ctrl, seconds_unfused=t_unfused, seconds_guided=t_guided,
               seconds_variants=t_variants,
               seconds_reference=t_ref, seconds_sketch=t_sketch, peak_mib=peak,
               checkpoint_mib=sizes, seconds_storyboard=t_board, seconds_overlay=t_overlay,
               dropout_windows_per_s=dropout,
               auto_precision=prec)
    return out


if __name__ == "__main__":
    main()
    sys.exit(0)
