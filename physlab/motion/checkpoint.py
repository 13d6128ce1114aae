"""Checkpoints of the motion generator: writing, safe reading, rebuilding the network.

A checkpoint (``torch.save`` dict, written atomically) holds everything needed to generate
and to resume: ``kind`` / ``version``, ``stage``, ``model_config``, ``train_config``,
``model`` (state dict), ``optimizer``, ``step``, per-rank ``rng`` states, ``feature_stats``,
``scheduler``, ``text_cache``, ``param_digests``, ``train_takes``. Reading never runs code
from the file (``torch.load(weights_only=True)``); numpy arrays are stored as tagged tensors.
Used by both :mod:`physlab.motion.train` and :mod:`physlab.motion.sampling` (sampling does
not depend on training).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import torch

from physlab._io import atomic_write

from .diffusion import NoiseScheduler
from .features import FeatureStats
from .model import ControlledDenoiser, DenoiserConfig, MotionDenoiser

__all__ = ["CHECKPOINT_KIND", "CHECKPOINT_VERSION", "NOTHING_LEFT_TO_TRAIN", "save_checkpoint",
           "load_checkpoint", "load_model", "export_weights"]

#: Identifies a physlab motion checkpoint (the name of the module that first wrote them).
CHECKPOINT_KIND = "physlab.motion.train"
#: 2: safe to load (``torch.load(weights_only=True)``): tensors, numbers, strings, lists and
#: dicts only — numpy arrays are stored as tagged tensors / string lists (:func:`_to_safe`).
#: 1 (before 2026-11): a general pickle, which can run code when loaded; refused.
CHECKPOINT_VERSION = 2
#: What the training CLIs print instead of a speed when a rerun (``make motion-model`` reruns
#: every stage) finds its checkpoint already at the steps asked for.
NOTHING_LEFT_TO_TRAIN = "nothing left to train (the checkpoint had the steps asked for)"

_NDARRAY, _STRARRAY = "__ndarray__", "__str_ndarray__"


def _to_safe(obj):
    """``obj`` with every numpy array / scalar replaced by what ``torch.load(weights_only=
    True)`` can read back without unpickling code: numeric arrays -> ``{"__ndarray__":
    tensor}``, string arrays -> ``{"__str_ndarray__": [str], "shape": [int]}``, numpy scalars
    -> Python numbers. Dicts, lists, tuples (as lists), tensors, str, numbers, None pass."""
    if isinstance(obj, dict):
        return {k: _to_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_to_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "US":
            return {_STRARRAY: [str(x) for x in obj.reshape(-1)], "shape": list(obj.shape)}
        return {_NDARRAY: torch.from_numpy(np.ascontiguousarray(obj).copy())}
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _from_safe(obj):
    """Inverse of :func:`_to_safe` (tagged entries back to numpy arrays)."""
    if isinstance(obj, dict):
        if set(obj) == {_NDARRAY}:
            return obj[_NDARRAY].numpy()
        if set(obj) == {_STRARRAY, "shape"}:
            return np.array(obj[_STRARRAY], dtype=str).reshape(obj["shape"])
        return {k: _from_safe(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_from_safe(v) for v in obj]
    return obj


def save_checkpoint(path, state):
    """``torch.save`` of ``state`` (made loadable with ``weights_only=True`` by
    :func:`_to_safe`) to ``path`` atomically; returns the Path."""
    safe = _to_safe(state)
    return atomic_write(path, lambda tmp: torch.save(safe, tmp), suffix=".pt")


def _last_line(e):
    """The informative line of torch's long weights-only error ("Unsupported operand 32")."""
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    useful = [ln for ln in lines if ln.startswith("Unsupported")] or lines[-1:]
    return useful[0][:160] if useful else type(e).__name__


def load_checkpoint(path):
    """Read a checkpoint written by :func:`train` / :func:`export_weights`.

    Loading never runs code from the file: ``torch.load(weights_only=True)`` accepts only
    tensors, numbers, strings, lists and dicts, so a crafted pickle is refused, not executed.

    FileNotFoundError if missing; ValueError if unreadable (truncated / corrupt / holding
    Python objects), not a physlab motion checkpoint, of another format version, or with
    non-finite weights (naming the parameter)."""
    import pickle

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}; train one with `python -m "
                                f"physlab.motion.train --stage base --out {path}`")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as e:
        found = re.search(r"Unsupported global: GLOBAL (\S+)", str(e))
        if not found:                              # not a pickle of objects: a damaged file
            raise ValueError(f"{path} is not a readable checkpoint (the file is damaged: "
                             f"{_last_line(e)}); it may be truncated or corrupt: delete it "
                             f"and retrain, or use an older copy") from None
        raise ValueError(
            f"{path} was refused: it holds Python objects that loading could execute, not "
            f"only tensors, numbers and strings (it asks for {found.group(1)}). physlab "
            f"never unpickles "
            f"those. A checkpoint of physlab before format version {CHECKPOINT_VERSION} "
            f"(2026-11) is such a file: retrain it (`make motion-model`, or the train "
            f"command in data/motion/README.md)") from None
    except Exception as e:  # noqa: BLE001 - torch raises many kinds for a corrupt file
        raise ValueError(f"{path} is not a readable checkpoint ({type(e).__name__}: {e}); "
                         f"it may be truncated or corrupt: delete it and retrain, or use an "
                         f"older copy") from None
    if not isinstance(ckpt, dict) or ckpt.get("kind") != CHECKPOINT_KIND:
        raise ValueError(f"{path} is not a physlab.motion.train checkpoint (no kind "
                         f"{CHECKPOINT_KIND!r})")
    if ckpt.get("version") != CHECKPOINT_VERSION:
        raise ValueError(f"{path} has checkpoint version {ckpt.get('version')}, this code "
                         f"reads version {CHECKPOINT_VERSION}")
    weights = ckpt.get("model")
    if not isinstance(weights, dict) or not all(torch.is_tensor(v) for v in weights.values()):
        raise ValueError(f"{path} has no state dict of tensors under 'model'")
    for name, v in weights.items():
        if v.is_floating_point() and not bool(torch.isfinite(v).all()):
            raise ValueError(f"checkpoint {path} has non-finite weights (NaN or inf) in "
                             f"{name!r}: it comes from a diverged training run; use an "
                             f"earlier checkpoint or retrain with a smaller --lr")
    return _from_safe(ckpt)


def _build(ckpt):
    cfg = DenoiserConfig.from_dict(ckpt["model_config"])
    base = MotionDenoiser(cfg)
    if ckpt["stage"] == "base":
        return base
    sketch = any(k.startswith("sketch_traj_encoder.") for k in ckpt["model"])
    return ControlledDenoiser(base, single_controlnet=ckpt["single_controlnet"],
                              double_controlnet=bool(ckpt.get("double_controlnet", False)),
                              sketch_encoders=sketch, control_head=has_control_head(ckpt))


def has_control_head(ckpt):
    """Whether a checkpoint's weights hold a control head (``ControlledDenoiser``'s
    ``control_head``, ``train --control-head``)."""
    return any(k.startswith("control_head.") for k in ckpt["model"])


def load_model(path_or_ckpt):
    """Rebuild the trained network and everything needed to sample with it.

    Returns
    -------
    dict: ``model`` (:class:`MotionDenoiser` or :class:`ControlledDenoiser`, eval mode,
    float32), ``scheduler`` (:class:`NoiseScheduler`), ``stats`` (:class:`FeatureStats`),
    ``text_cache`` (:class:`EmbeddingCache`), ``config`` (:class:`DenoiserConfig`),
    ``stage``, ``step``.
    """
    from .text import EmbeddingCache

    ckpt = path_or_ckpt if isinstance(path_or_ckpt, dict) else load_checkpoint(path_or_ckpt)
    model = _build(ckpt)
    model.load_state_dict({k: v.float() for k, v in ckpt["model"].items()})
    model.eval()
    scheduler = NoiseScheduler.from_dict(ckpt["scheduler"])
    (model if isinstance(model, MotionDenoiser) else model.base).set_schedule(
        scheduler.alphas_cumprod)                                          # config.skip only
    return {"model": model, "scheduler": scheduler,
            "stats": FeatureStats(**ckpt["feature_stats"]),
            "text_cache": EmbeddingCache.from_state_dict(ckpt["text_cache"]),
            "config": model.config, "stage": ckpt["stage"], "step": ckpt["step"]}


def export_weights(src, dst, dtype=torch.float16):
    """Write an inference-only copy of a checkpoint (no optimizer / RNG states; weights cast
    to ``dtype``); :func:`load_model` reads it. Returns the Path."""
    ckpt = load_checkpoint(src)
    small = {k: v for k, v in ckpt.items() if k not in ("optimizer", "rng")}
    small["model"] = {k: v.to(dtype) if v.is_floating_point() else v
                      for k, v in ckpt["model"].items()}
    return save_checkpoint(dst, small)
