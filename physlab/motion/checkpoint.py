"""Checkpoints of the motion generator: writing, safe reading, rebuilding the network.

A checkpoint (``torch.save`` dict, written atomically) holds everything needed to generate
and to resume: ``kind`` / ``version``, ``stage``, ``model_config``, ``train_config``,
``model`` (state dict), ``optimizer``, ``step``, per-rank ``rng`` states, ``feature_stats``,
``scheduler``, ``text_cache``, ``param_digests``, ``train_takes``, and in a shipped control
checkpoint optionally ``text_model`` (:func:`attach_text_model`: a separate base for text-only
requests). Reading never runs code from the file (``torch.load(weights_only=True)``); numpy
arrays are stored as tagged tensors.
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
           "load_checkpoint", "load_model", "export_weights", "attach_text_model"]

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
    _check_weights(path, ckpt.get("model"), "model")
    text = ckpt.get("text_model")
    if text is not None:
        if not isinstance(text, dict) or not isinstance(text.get("model_config"), dict):
            raise ValueError(f"{path} has a 'text_model' entry without a 'model_config'; "
                             f"re-attach the text model ({ATTACH_COMMAND})")
        _check_weights(path, text.get("model"), "text_model.model")
    return _from_safe(ckpt)


def _check_weights(path, weights, key):
    """ValueError unless ``weights`` is a state dict of finite tensors."""
    if not isinstance(weights, dict) or not all(torch.is_tensor(v) for v in weights.values()):
        raise ValueError(f"{path} has no state dict of tensors under {key!r}")
    for name, v in weights.items():
        if v.is_floating_point() and not bool(torch.isfinite(v).all()):
            raise ValueError(f"checkpoint {path} has non-finite weights (NaN or inf) in "
                             f"{name!r}: it comes from a diverged training run; use an "
                             f"earlier checkpoint or retrain with a smaller --lr")


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
    ``stage``, ``step``, ``text_model`` (:class:`MotionDenoiser` for text-only requests, eval,
    float32, or None: :func:`attach_text_model`), ``text_stats`` (its own
    :class:`FeatureStats` where they differ from ``stats``, else None), ``text_guidance``
    (its default text guidance scale, or None: :func:`attach_text_model`).
    """
    from .text import EmbeddingCache

    ckpt = path_or_ckpt if isinstance(path_or_ckpt, dict) else load_checkpoint(path_or_ckpt)
    model = _build(ckpt)
    model.load_state_dict({k: v.float() for k, v in ckpt["model"].items()})
    model.eval()
    scheduler = NoiseScheduler.from_dict(ckpt["scheduler"])
    (model if isinstance(model, MotionDenoiser) else model.base).set_schedule(
        scheduler.alphas_cumprod)                                          # config.skip only
    text_model = text_stats = text_guidance = None
    if ckpt.get("text_model") is not None:
        text_model = MotionDenoiser(DenoiserConfig.from_dict(ckpt["text_model"]["model_config"]))
        text_model.load_state_dict({k: v.float() for k, v in ckpt["text_model"]["model"].items()})
        text_model.eval().set_schedule(scheduler.alphas_cumprod)
        if ckpt["text_model"].get("feature_stats") is not None:
            text_stats = FeatureStats(**ckpt["text_model"]["feature_stats"])
        text_guidance = check_text_guidance(ckpt["text_model"].get("guidance"),
                                            "text_model.guidance")
    return {"model": model, "scheduler": scheduler,
            "stats": FeatureStats(**ckpt["feature_stats"]),
            "text_cache": EmbeddingCache.from_state_dict(ckpt["text_cache"]),
            "config": model.config, "stage": ckpt["stage"], "step": ckpt["step"],
            "text_model": text_model, "text_stats": text_stats,
            "text_guidance": text_guidance}


def export_weights(src, dst, dtype=torch.float16):
    """Write an inference-only copy of a checkpoint (no optimizer / RNG states; weights cast
    to ``dtype``); :func:`load_model` reads it. Returns the Path."""
    ckpt = load_checkpoint(src)
    small = {k: v for k, v in ckpt.items() if k not in ("optimizer", "rng")}
    small["model"] = _cast(ckpt["model"], dtype)
    return save_checkpoint(dst, small)


def _cast(weights, dtype):
    """A state dict with its floating-point tensors cast to ``dtype``."""
    return {k: v.to(dtype) if v.is_floating_point() else v for k, v in weights.items()}


#: How a text model is attached (the error messages point here).
ATTACH_COMMAND = ("python -m physlab.motion.checkpoint attach-text CONTROL.pt TEXT_BASE.pt")
#: Model-config fields a text model must share with the control checkpoint's base: the
#: sampler reads the clip length, features and output basis from the control model.
SHARED_CONFIG = ("feature_dim", "n_frames", "text_dim", "max_timesteps", "representation",
                 "smooth_basis")


def check_text_guidance(guidance, name="guidance"):
    """``guidance`` checked: None, a float or a pair ``(w_high, w_low)``
    (:func:`~physlab.motion.conditions.check_guidance`); ValueError naming ``name``."""
    from .conditions import check_guidance

    return None if guidance is None else check_guidance(guidance, name)


def attach_text_model(control, text_base, out=None, dtype=torch.float16, guidance=None):
    """Write ``control`` (a control-stage checkpoint) with the network of ``text_base`` (a
    base-stage checkpoint) attached as its ``text_model``: :class:`~physlab.motion.sampling.
    Generator` then samples text-only requests with it and everything with a keypose,
    trajectories or a drawing with the control model, as before.

    Why (docs/motion_experiments.md): the ControlNet's frozen base must be an x₀ network (a
    base with EDM's skip connection follows text better but loses control accuracy), and that
    x₀ base overwrites rare actions (backwards walks, waves) with its own. Sketch2Anim samples
    text only from the ControlNet's base; this is physlab's deviation, and a control
    checkpoint without a text model keeps the paper's behaviour.

    Both must come from the same data and noise schedule: the feature means, scheduler,
    training takes and :data:`SHARED_CONFIG` fields are compared, and a mismatch is a
    ValueError naming the field. Feature scales (std) may differ (a text base trained with a
    finer pelvis path scale, ``train --pelvis-scale``): the text model then carries its own
    statistics, and the generator decodes its clips with them. ``guidance`` (None, a number
    or a pair ``(w_high, w_low)``: :func:`~physlab.motion.conditions.check_guidance`) is the
    text model's own default text guidance scale w, stored with it: :attr:`Generator.text_guidance
    <physlab.motion.sampling.Generator.text_guidance>` (None: the generator's
    :data:`~physlab.motion.sampling.TEXT_GUIDANCE`); a model trained longer follows its text
    less at the same w and needs a larger one. ``out`` (default: ``control`` itself) is
    written atomically; the text model's weights are cast to ``dtype`` (fp16, as
    :func:`export_weights`). Returns the Path written."""
    guidance = check_text_guidance(guidance)
    ctrl, text = load_checkpoint(control), load_checkpoint(text_base)
    if ctrl.get("stage") not in ("control", "align"):
        raise ValueError(f"{control} is a {ctrl.get('stage')!r} checkpoint; give a control "
                         f"checkpoint (`python -m physlab.motion.train --stage control`) first")
    if text.get("stage") != "base":
        raise ValueError(f"{text_base} is a {text.get('stage')!r} checkpoint; the text model "
                         f"must be a base (`python -m physlab.motion.train --stage base`)")
    a, b = ctrl["model_config"], text["model_config"]
    for field in SHARED_CONFIG:
        if a.get(field) != b.get(field):
            raise ValueError(f"model_config.{field} differs: {control} has {a.get(field)!r}, "
                             f"{text_base} {b.get(field)!r}; train the text base with the "
                             f"control model's settings")
    if not np.allclose(ctrl["feature_stats"]["mean"], text["feature_stats"]["mean"],
                       rtol=1e-6, atol=1e-9):
        raise ValueError(f"feature_stats.mean differs between {control} and {text_base}: "
                         f"they were trained on different clips; train both on the same data")
    same_std = np.allclose(ctrl["feature_stats"]["std"], text["feature_stats"]["std"],
                           rtol=1e-6, atol=1e-9)
    sa, sb = NoiseScheduler.from_dict(ctrl["scheduler"]), NoiseScheduler.from_dict(
        text["scheduler"])
    if not torch.allclose(sa.alphas_cumprod, sb.alphas_cumprod):
        raise ValueError(f"the noise schedules of {control} and {text_base} differ; train the "
                         f"text base with the control model's schedule")
    if sorted(ctrl.get("train_takes") or ()) != sorted(text.get("train_takes") or ()):
        raise ValueError(f"train_takes differ: {control} was trained on "
                         f"{ctrl.get('train_takes')}, {text_base} on {text.get('train_takes')}; "
                         f"a held-out take must stay held out for both")
    ctrl["text_model"] = {
        "model_config": b, "step": text.get("step"), "train_config": text.get("train_config"),
        "model": _cast(text["model"], dtype)}
    if guidance is not None:
        ctrl["text_model"]["guidance"] = list(guidance) if isinstance(guidance, tuple) \
            else guidance
    if not same_std:            # e.g. a finer pelvis path scale (train --pelvis-scale)
        ctrl["text_model"]["feature_stats"] = {k: np.asarray(v, dtype=float).copy()
                                               for k, v in text["feature_stats"].items()}
    return save_checkpoint(control if out is None else out, ctrl)


PROG = "python -m physlab.motion.checkpoint"


def _attach_command(argv):
    from physlab._cli import Parser

    from .conditions import format_guidance, guidance_argument

    p = Parser(prog=PROG, description="Tools for motion checkpoints.")
    sub = p.add_subparsers(dest="command", required=True)
    at = sub.add_parser("attach-text", help=attach_text_model.__doc__.split("\n\n")[0])
    at.add_argument("control", help="control-stage checkpoint (rewritten unless --out)")
    at.add_argument("text_base", help="base-stage checkpoint whose network takes text only")
    at.add_argument("--out", default=None, help="write here instead of CONTROL")
    at.add_argument("--guidance", type=guidance_argument, default=None,
                    help="the text model's own default text guidance scale: W, or HIGH,LOW "
                         "(HIGH at the upper half of the noise levels, LOW below; default: "
                         "the generator's, physlab.motion.sampling.TEXT_GUIDANCE)")
    args = p.parse_args(argv)
    path = attach_text_model(args.control, args.text_base, args.out, guidance=args.guidance)
    w = "" if args.guidance is None else f" (text guidance w = {format_guidance(args.guidance)})"
    print(f"text model of {args.text_base} attached{w} -> {path}")


def main(argv=None):
    """``python -m physlab.motion.checkpoint attach-text CONTROL TEXT_BASE [--out OUT]``: one-
    line errors with exit status 2 (``--debug``: the traceback), as every physlab command."""
    from physlab._cli import guard

    status = guard(PROG, _attach_command, argv)
    if status:
        raise SystemExit(status)


if __name__ == "__main__":
    main()
