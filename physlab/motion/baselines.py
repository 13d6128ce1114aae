"""The three baselines of Sketch2Anim's Table 1 (Sec. 7.1, supp. F), on physlab's data.

* :class:`MotionRetrieval` — **motion retrieval**: among the training windows of the asked
  action (the action text's MiniLM embedding, nearest training text), the window whose 2D
  keypose and trajectories, projected in the sketch's camera, are nearest to the drawing.
  The result is real mocap, so it moves well but follows the sketch only as far as the
  database allows.
* :class:`Lifter` + :func:`lift_and_control` — **lift-and-control**: a network lifts the
  drawn keypose and trajectories (with the camera) to 3D, and the 3D generator takes them as
  3D conditions. Trained here (:func:`train_lifter`) on the same projected pairs as the 2D
  encoders (:func:`~physlab.motion.align.sketch_batch`).
* **direct 2D-to-motion** — the generator's ControlNet and adapter trained directly on 2D
  conditions, with 2D encoders from the start (``python -m physlab.motion.train --stage
  control --direct-2d``); it needs no baseline code here, only another checkpoint.
"""
from __future__ import annotations

import dataclasses
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .dataset import JOINT_NAMES, TRAJECTORY_JOINT_NAMES, TRAJECTORY_JOINTS

__all__ = ["MotionRetrieval", "Lifter", "LifterConfig", "train_lifter", "load_lifter",
           "lift_and_control", "DEFAULT_LIFTER"]

#: The shipped lifter of the lift-and-control baseline (``python -m physlab.motion.baselines
#: train-lifter``).
DEFAULT_LIFTER = Path(__file__).resolve().parents[2] / "data" / "motion" / "sketch_lifter.pt"
LIFTER_STAGE = "lifter"


def _sketch_arrays(keypose_2d, trajectories_2d, keypose_at, n_frames):
    """Dense (N, 6, 2) trajectory, (N, 6) mask, keypose (22, 2) or None, key frame."""
    from .sampling import build_sketch
    from .camera import Camera

    sk = build_sketch(keypose_2d, keypose_at, trajectories_2d, Camera(), n_frames=n_frames)
    return sk["trajectory"], sk["traj_mask"], sk["keypose"], sk["key_frame"]


# ----------------------------------------------------------------------------- retrieval


class MotionRetrieval:
    """Nearest training window to a sketch (module docstring).

    Parameters
    ----------
    windows : (M, 40, 22, 3) canonical training windows (m).
    texts : list of M action texts.
    contents : optional list of M action labels (``walk``, ``kick``, ...): the windows of the
        nearest text's label in every style are searched, not only those of that text.
    text_embed : callable ``list of str -> (n, 384)`` unit embeddings (default: the MiniLM
        :class:`~physlab.motion.text.EmbeddingCache` of the shipped generator's checkpoint,
        which holds every training text).
    keypose_weight : weight of the keypose distance against the trajectory distance.
    """

    def __init__(self, windows, texts, contents=None, text_embed=None, keypose_weight=1.0):
        self.windows = np.asarray(windows, dtype=float)
        if self.windows.ndim != 4 or self.windows.shape[2:] != (len(JOINT_NAMES), 3):
            raise ValueError(f"windows must have shape (M, N, 22, 3), got {self.windows.shape}")
        if len(texts) != len(self.windows):
            raise ValueError(f"{len(texts)} texts for {len(self.windows)} windows")
        self.texts = list(texts)
        self.contents = None if contents is None else list(contents)
        if self.contents is not None and len(self.contents) != len(self.texts):
            raise ValueError(f"{len(self.contents)} contents for {len(self.texts)} texts")
        self.vocab = sorted(set(self.texts))
        self._embed = text_embed
        self._vocab_emb = None
        self.keypose_weight = float(keypose_weight)

    @classmethod
    def from_training_data(cls, data_root=None, **kwargs):
        """The database of every training window (every Bandai-Namco take but the held-out
        002), 40 frames, stride 10."""
        from .train import training_windows

        win, _ = training_windows(data_root)
        return cls(win.joints, win.text, contents=win.content, **kwargs)

    def _embedder(self):
        if self._embed is None:
            from .sampling import load_generator

            cache = load_generator().text_cache
            self._embed = lambda texts: np.stack([cache.get(t) for t in texts])
        return self._embed

    def candidates(self, action):
        """Indices of the windows of the training text nearest to ``action``."""
        emb = self._embedder()
        if self._vocab_emb is None:
            self._vocab_emb = np.asarray(emb(self.vocab), dtype=float)
        q = np.asarray(emb([action]), dtype=float)[0]
        best = self.vocab[int(np.argmax(self._vocab_emb @ q))]
        if self.contents is None:
            return np.array([i for i, t in enumerate(self.texts) if t == best])
        label = self.contents[self.texts.index(best)]
        return np.array([i for i, c in enumerate(self.contents) if c == label])

    def __call__(self, action, keypose_2d=None, trajectories_2d=None, camera=None,
                 keypose_at="first", **_ignored):
        """``(40, 22, 3)`` joints of the nearest window (the canonical frame, like the
        generator's output)."""
        from .camera import Camera

        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a physlab.motion.camera.Camera, got {camera!r}")
        N = self.windows.shape[1]
        traj, mask, key, kf = _sketch_arrays(keypose_2d, trajectories_2d, keypose_at, N)
        idx = self.candidates(action)
        cand = self.windows[idx]                                             # (K, N, 22, 3)
        cost = np.zeros(len(idx))
        if mask.any():
            p = camera.project(cand[:, :, list(TRAJECTORY_JOINTS)])          # (K, N, 6, 2)
            d = np.linalg.norm(p - traj[None], axis=-1)                      # (K, N, 6)
            cost += (d * mask[None]).sum((1, 2)) / mask.sum()
        if key is not None:
            p = camera.project(cand[:, kf])                                  # (K, 22, 2)
            rel = p - p[:, :1]
            cost += self.keypose_weight * np.linalg.norm(rel - (key - key[:1])[None],
                                                         axis=-1).mean(1)
        return cand[int(np.argmin(cost))].copy()


# ----------------------------------------------------------------------------- lifting


@dataclass
class LifterConfig:
    """Sizes of the lifting network (saved in its checkpoint)."""
    d_model: int = 128
    n_heads: int = 4
    n_layers: int = 3
    ff: int = 256
    n_frames: int = 40

    def to_dict(self):
        return dataclasses.asdict(self)


def _lifter_module():
    import torch
    from torch import nn

    from .model import CAMERA_FEATURES, N_JOINTS, N_TRAJ, camera_features

    class Lifter(nn.Module):
        """2D sketch -> 3D condition: a transformer over one token per frame (the frame's
        drawn trajectory points, mask and camera features) plus 22 joint tokens of the drawn
        keypose (pelvis-relative, with a learned key-frame embedding); heads read the 3D
        trajectory points of each frame and the 3D keypose (pelvis-relative in x and z,
        height absolute, like the 3D keypose encoder's input)."""

        def __init__(self, cfg: LifterConfig):
            super().__init__()
            C = cfg.d_model
            self.config = cfg
            self.frame_in = nn.Linear(3 * N_TRAJ + CAMERA_FEATURES, C)
            self.joint_in = nn.Linear(2 + CAMERA_FEATURES, C)
            self.pos = nn.Parameter(torch.randn(1, cfg.n_frames + N_JOINTS, C) * 0.02)
            self.key_frame = nn.Embedding(cfg.n_frames, C)
            layer = nn.TransformerEncoderLayer(C, cfg.n_heads, cfg.ff, dropout=0.0,
                                               batch_first=True, norm_first=True)
            self.encoder = nn.TransformerEncoder(layer, cfg.n_layers,
                                                 enable_nested_tensor=False)
            self.traj_out = nn.Linear(C, 3 * N_TRAJ)
            self.key_out = nn.Linear(C, 3)

        def forward(self, trajectory_2d, mask, keypose_2d, key_frame, camera):
            B, N = mask.shape[:2]
            cam = camera_features(camera)                                   # (B, 7)
            m = mask.to(trajectory_2d.dtype)
            frames = torch.cat([(trajectory_2d * m[..., None]).flatten(2), m,
                                cam[:, None].expand(-1, N, -1)], dim=-1)
            rel = keypose_2d - keypose_2d[:, :1]
            joints = torch.cat([rel, cam[:, None].expand(-1, N_JOINTS, -1)], dim=-1)
            h = torch.cat([self.frame_in(frames),
                           self.joint_in(joints) + self.key_frame(key_frame)[:, None]], 1)
            h = self.encoder(h + self.pos)
            traj = self.traj_out(h[:, :N]).reshape(B, N, N_TRAJ, 3)
            key = self.key_out(h[:, N:])                                     # (B, 22, 3)
            return traj, key

    return Lifter


def Lifter(cfg: LifterConfig | None = None):
    """The lifting network (a torch module; built lazily so that importing this module does
    not import torch)."""
    return _lifter_module()(cfg or LifterConfig())


def _lifter_loss(lifter, cond, sketch):
    import torch

    traj, key = lifter(sketch["trajectory_2d"], sketch["traj_mask_2d"], sketch["keypose_2d"],
                       cond["key_frame"], sketch["camera"])
    m = cond["traj_mask"].to(traj.dtype)
    l_tr = (m * ((traj - cond["trajectory"]) ** 2).sum(-1)).sum() / m.sum().clamp(min=1)
    k = cond["keypose"].clone()
    k[..., [0, 2]] -= k[:, :1, [0, 2]]
    l_key = ((key - k) ** 2).sum(-1).mean()
    return l_tr + l_key, torch.stack([l_tr, l_key]).detach()


def train_lifter(out, steps=3000, batch_size=64, lr=3e-4, seed=0, data_root=None,
                 num_threads=0, max_clips=0, progress=True, checkpoint_every=500):
    """Train the lift-and-control lifter on projected training windows (the 2D encoders'
    pairs: random Cross conditions, random views, proportion and joint noise) with the
    squared 3D error of the trajectory points and of the keypose; resumable from ``out``.
    Returns ``{"path", "step", "loss"}``."""
    import torch
    from tqdm.auto import tqdm

    from .align import sketch_batch
    from .checkpoint import CHECKPOINT_KIND, CHECKPOINT_VERSION, load_checkpoint, \
        save_checkpoint
    from .train import condition_batch, training_windows

    if num_threads:
        torch.set_num_threads(int(num_threads))
    out = Path(out)
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    g = torch.Generator().manual_seed(seed)
    joints = training_windows(data_root, max_clips)[0].joints
    cfg = LifterConfig()
    lifter = Lifter(cfg)
    opt = torch.optim.AdamW(lifter.parameters(), lr=lr, weight_decay=0.01)
    step = 0
    if out.is_file():
        ck = load_checkpoint(out)
        if ck["stage"] != LIFTER_STAGE:
            raise ValueError(f"{out} holds a '{ck['stage']}' checkpoint, not a lifter; use "
                             f"another path")
        lifter.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        step = int(ck["step"])
    loss_v = float("nan")

    def save():
        save_checkpoint(out, {"kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION,
                              "stage": LIFTER_STAGE, "model_config": cfg.to_dict(),
                              "model": lifter.state_dict(), "optimizer": opt.state_dict(),
                              "step": step, "loss": loss_v})

    bar = tqdm(total=steps, initial=step, desc="train lifter", disable=not progress)
    while step < steps:
        for group in opt.param_groups:
            group["lr"] = lr * 0.5 * (1 + np.cos(np.pi * step / steps))
        idx = torch.randint(len(joints), (batch_size,), generator=g).numpy()
        cond = condition_batch(joints[idx], rng)
        sketch = sketch_batch(cond, rng)
        loss, _ = _lifter_loss(lifter, cond, sketch)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(lifter.parameters(), 1.0)
        opt.step()
        step += 1
        loss_v = loss.item()
        bar.update(1)
        bar.set_postfix(loss=f"{loss_v:.4f}")
        if step % checkpoint_every == 0 or step == steps:
            save()
    bar.close()
    return {"path": out, "step": step, "loss": loss_v}


def load_lifter(path=None):
    """The trained lifter (eval mode); FileNotFoundError with the training command."""
    from .checkpoint import load_checkpoint

    path = Path(path or DEFAULT_LIFTER)
    if not path.is_file():
        raise FileNotFoundError(f"no lifter at {path}; train one with `python -m "
                                f"physlab.motion.baselines train-lifter --out {path}`")
    ck = load_checkpoint(path)
    if ck["stage"] != LIFTER_STAGE:
        raise ValueError(f"{path} holds a '{ck['stage']}' checkpoint, not a lifter")
    lifter = Lifter(LifterConfig(**ck["model_config"]))
    lifter.load_state_dict({k: v.float() for k, v in ck["model"].items()})
    return lifter.eval()


def lift(lifter, keypose_2d=None, trajectories_2d=None, camera=None, keypose_at="first",
         n_frames=40):
    """The 3D conditions a lifter reads from a sketch: ``(keypose_3d or None,
    trajectories_3d or None)`` in the keywords of :func:`physlab.motion.generate`."""
    import torch

    traj, mask, key, kf = _sketch_arrays(keypose_2d, trajectories_2d, keypose_at, n_frames)
    cam = torch.tensor([[camera.scale, camera.pitch, camera.yaw, camera.roll]],
                       dtype=torch.float32)
    k2 = np.zeros((len(JOINT_NAMES), 2)) if key is None else key
    with torch.no_grad():
        t3, k3 = lifter(torch.tensor(traj, dtype=torch.float32)[None],
                        torch.tensor(mask)[None], torch.tensor(k2, dtype=torch.float32)[None],
                        torch.tensor([kf]), cam)
    t3, k3 = t3[0].double().numpy(), k3[0].double().numpy()
    trajs = {name: t3[mask[:, c], c] for c, name in enumerate(TRAJECTORY_JOINT_NAMES)
             if mask[:, c].any()}
    return (k3 if key is not None else None), (trajs or None)


def lift_and_control(action, keypose_2d=None, trajectories_2d=None, camera=None,
                     keypose_at="first", lifter=None, generator=None, **options):
    """The lift-and-control baseline: :func:`lift`, then the 3D generator (``options``: its
    keywords, e.g. ``guidance_final=0`` for the networks alone)."""
    from .sampling import load_generator

    lifter = lifter if lifter is not None else load_lifter()
    gen = generator if generator is not None else load_generator()
    k3, t3 = lift(lifter, keypose_2d, trajectories_2d, camera, keypose_at)
    return gen(action, keypose_3d=k3, trajectories_3d=t3, keypose_at=keypose_at, **options)


def main(argv=None):
    import argparse

    p = argparse.ArgumentParser(prog="python -m physlab.motion.baselines",
                                description="Train the lift-and-control lifter.")
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train-lifter", help="train the 2D -> 3D lifter")
    t.add_argument("--out", default=str(DEFAULT_LIFTER))
    t.add_argument("--steps", type=int, default=3000)
    t.add_argument("--num-threads", type=int, default=0)
    t.add_argument("--max-clips", type=int, default=0)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--no-progress", action="store_true")
    t.add_argument("--export", default="", help="after training, write an fp16 inference "
                                                 "copy to this path")
    a = p.parse_args(argv)
    tic = time.perf_counter()
    res = train_lifter(a.out, steps=a.steps, seed=a.seed, num_threads=a.num_threads,
                       max_clips=a.max_clips, progress=not a.no_progress)
    print(f"lifter: step {res['step']}, loss {res['loss']:.4f}, "
          f"{time.perf_counter() - tic:.0f} s -> {res['path']}")
    if a.export:
        from .checkpoint import export_weights

        print(f"inference weights (fp16) -> {export_weights(res['path'], a.export)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
