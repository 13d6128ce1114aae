"""Which joints carry the text-only jerk? (docs/motion_experiments.md, "Between 4 and 8").

For the held-out Bandai-Namco windows (take 002; ``../shared/data``) and for text-only clips
of each checkpoint from those windows' texts (seed = window index, the generator's defaults,
w = 2.5), prints the plain area under the jerk curve (:func:`physlab.motion.metrics.jerk`
with ``reference = 0``, m/frame³ summed over frames) of every joint, and of the pelvis, legs,
arms and trunk alone (the curve's max over that group's joints)::

    python scripts/jerk_by_joints.py data/motion/sketch2anim_control.pt runs/text_base.pt

A base checkpoint samples on its own; a control checkpoint's text only comes from its text
model, as ``generate`` does.
"""
from __future__ import annotations

import argparse

import numpy as np


def joint_groups():
    """``{"pelvis": [0], "legs": [...], "arms": [...], "trunk": [...]}``: indices into
    :data:`~physlab.motion.skeleton.JOINT_NAMES`; the arms are the sampler's
    (:data:`~physlab.motion.sampling.ARM_JOINTS`); every joint in exactly one group."""
    from physlab.motion.sampling import ARM_JOINTS
    from physlab.motion.skeleton import JOINT_NAMES

    legs = [i for i, n in enumerate(JOINT_NAMES)
            if any(k in n for k in ("hip", "knee", "ankle", "foot"))]
    arms = [i for i, n in enumerate(JOINT_NAMES) if n in ARM_JOINTS]
    trunk = [i for i in range(1, len(JOINT_NAMES)) if i not in legs + arms]
    return {"pelvis": [0], "legs": legs, "arms": arms, "trunk": trunk}


def jerk_by_group(joints):
    """``{"all": a, "pelvis": …, "legs": …, "arms": …, "trunk": …}``: the plain AUJ of
    ``(B, T, 22, 3)`` joints (m) over every joint and over each group's joints."""
    from physlab.motion.metrics import jerk

    x = np.asarray(joints, dtype=float)
    out = {"all": float(jerk(x)[0])}
    for name, idx in joint_groups().items():
        out[name] = float(jerk(x[:, :, idx])[0])
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkpoints", nargs="+")
    ap.add_argument("--windows", type=int, default=64)
    ap.add_argument("--num-threads", type=int, default=2)
    args = ap.parse_args(argv)
    if args.windows < 1:
        ap.error(f"--windows must be >= 1, got {args.windows}")
    import torch

    from physlab.motion.evaluate import held_out_windows
    from physlab.motion.sampling import Generator

    torch.set_num_threads(args.num_threads)
    data = held_out_windows(args.windows)
    rows = [("real clips", jerk_by_group(data["joints"]))]
    for path in args.checkpoints:
        gen = Generator.from_checkpoint(path)
        clips = np.stack([gen(t, seed=i) for i, t in enumerate(data["text"])])
        rows.append((path, jerk_by_group(clips)))
    keys = list(rows[0][1])
    print(f"Plain AUJ (m/frame³, reference 0) of {len(data['text'])} held-out windows and "
          f"their texts' text-only clips:\n")
    print("| clips | " + " | ".join(keys) + " |")
    print("|---|" + "---|" * len(keys))
    for name, r in rows:
        print(f"| {name} | " + " | ".join(f"{r[k]:.3f}" for k in keys) + " |")


if __name__ == "__main__":
    main()
