"""A soft DCT taper instead of the sampler's hard frequency cut (docs/motion_experiments.md,
"Tried, not kept: a soft frequency taper").

Every DCT frequency below A keeps weight 1, the weight falls along a raised cosine to 0 at B,
and the rest is dropped; the taper replaces the sampler's main cut (``--frequencies``,
default :data:`~physlab.motion.sampling.TEXT_FREQUENCIES`; the pelvis-path and legs-and-trunk
cuts stay, so give ``--body-frequencies`` another value than the main cut), then
``physlab.motion.evaluate`` runs with the remaining arguments::

    python scripts/frequency_taper.py 7 13 --control data/motion/sketch2anim_control.pt --windows 64
    python scripts/frequency_taper.py 7 13 --control data/motion/sketch2anim_control.pt --no-3d \
        --adherence --adherence-seeds 32

The taper is not a projection (applying it twice attenuates more); the sampler applies it to
every step's x̂₀, so the returned clip carries it once, from the last step.
"""
from __future__ import annotations

import math
import sys


def taper_matrix(n, a, b):
    """``(n, n)`` float32 ``Cᵀ diag(w) C`` with ``C`` the orthonormal DCT-II matrix and ``w``
    1 below frequency ``a``, ``½(1 + cos(π (k − a) / (b − a)))`` for ``a <= k < b``, 0 above."""
    import torch

    if not 0 <= a < b:
        raise ValueError(f"need 0 <= A < B, got A={a}, B={b}")
    k = torch.arange(n, dtype=torch.float64)
    w = torch.where(k < a, 1.0, torch.where(k >= b, 0.0,
                                            0.5 * (1 + torch.cos(math.pi * (k - a) / (b - a)))))
    C = torch.cos(math.pi * (k[None] + 0.5) * k[:, None] / n) * math.sqrt(2.0 / n)  # as in
    C[0] /= math.sqrt(2.0)                                    # model.low_pass_matrix
    return (C.T @ (w[:, None] * C)).to(torch.float32)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) < 2:
        raise SystemExit(__doc__)
    try:
        a, b = float(argv[0]), float(argv[1])
    except ValueError:
        raise SystemExit(f"A and B must be numbers, got {argv[:2]}\n\n{__doc__}")
    if not 0 <= a < b:
        raise SystemExit(f"need 0 <= A < B, got A={a}, B={b}")
    import physlab.motion.sampling as sampling
    from physlab.motion import evaluate

    cut = sampling.TEXT_FREQUENCIES
    if "--frequencies" in argv:
        cut = int(argv[argv.index("--frequencies") + 1])
    hard = sampling.low_pass_matrix

    def low_pass(n, k):           # only the main cut; the path / body passes stay hard cuts
        return taper_matrix(n, a, b) if k == cut else hard(n, k)

    sampling.low_pass_matrix = low_pass                              # Generator looks it up
    evaluate.main(argv[2:])


if __name__ == "__main__":
    main()
