"""Demos for lesson 10: from a 2D sketch to 3D motion (Zhong et al. 2025, "Sketch2Anim",
Secs. 3, 5, 6, supp. B, C, F, G).

The camera, the augmentations, the 2D encoders, the alignment losses, the baselines and the
sketch logic live in :mod:`physlab.motion` (``camera``, ``model``, ``align``, ``baselines``,
``sketch``) and the canvas in :mod:`physlab.viz.sketch_canvas`; this module draws the lesson's
figures and computes its small tables. Joints are ``(T, 22, 3)`` metres in the canonical frame;
2D points are normalised image units (``v`` up) unless a name says ``px``.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from physlab.motion.camera import Camera, perturb_joints, perturb_proportions, random_camera
from physlab.motion.dataset import TRAJECTORY_JOINTS
from physlab.motion.metrics import trajectory_error
from physlab.motion.skeleton import JOINT_NAMES, PARENTS
from physlab.viz.plots import new_figure

__all__ = ["EXAMPLE_SKETCH", "lesson_pose", "lesson_window", "views_figure",
           "alignment_terms", "embedding_similarity_figure", "guidance_steps",
           "guidance_steps_figure", "baselines_comparison", "baselines_figure",
           "draw_2d", "example_sketch", "trajectory_error_2d"]

DATA = Path(__file__).resolve().parents[2] / "data" / "motion"
#: A stick figure with a pelvis stroke, drawn in the canvas (lesson 10's starting sketch).
EXAMPLE_SKETCH = DATA / "example_sketch.json"
FIG_DPI = 80
_BONES = [(int(PARENTS[j]), j) for j in range(1, len(JOINT_NAMES))]
_LEFT = {j for j, n in enumerate(JOINT_NAMES) if n.startswith("left")}


def lesson_window(k=2):
    """A held-out real window shipped in ``data/motion/lesson_windows.npz`` (canonical) and
    its text."""
    d = np.load(DATA / "lesson_windows.npz")
    return d["held_out"][k], str(d["held_out_text"][k])


def lesson_pose(k=2, frame=0):
    """One real pose (22, 3) of :func:`lesson_window`."""
    return lesson_window(k)[0][frame]


def _share_limits(axes):
    """One x and one y range for all panels (the union of theirs), equal aspect, small ticks
    that do not run into each other."""
    from matplotlib.ticker import MaxNLocator

    lim = np.array([ax.get_xlim() + ax.get_ylim() for ax in axes])
    for ax in axes:
        ax.set_xlim(lim[:, 0].min(), lim[:, 1].max())
        ax.set_ylim(lim[:, 2].min(), lim[:, 3].max())
        ax.set_aspect("equal", adjustable="box")
        ax.xaxis.set_major_locator(MaxNLocator(2))
        ax.tick_params(labelsize=6)


def draw_2d(ax, uv, color="k", lw=1.6, alpha=1.0, sides=True, label=None):
    """A 2D stick figure (normalised units, v up) on ``ax``; the character's left limbs a
    shade lighter when ``sides``."""
    for a, b in _BONES:
        c = color
        if sides and b in _LEFT and color == "k":
            c = "0.45"
        ax.plot(uv[[a, b], 0], uv[[a, b], 1], color=c, lw=lw, alpha=alpha,
                solid_capstyle="round", label=label if (a, b) == _BONES[0] else None)
    ax.plot(*uv[15], "o", color=color, ms=5, alpha=alpha)


def views_figure(pose=None, seed=0, n=4):
    """One pose seen under ``n`` random storyboard views (top row) and, in a fixed front
    view, ``n`` random body-proportion perturbations + joint noise (bottom row): what the 2D
    encoders are trained on (supp. B)."""
    pose = lesson_pose() if pose is None else np.asarray(pose, dtype=float)
    rng = np.random.default_rng(seed)
    fig, axes = new_figure(ncols=n, nrows=2, width=1.45, height=2.3)
    axes = axes.reshape(2, n)
    front = Camera()
    for k in range(n):
        cam = random_camera(rng)
        ax = axes[0, k]
        draw_2d(ax, cam.project(pose))
        ax.set_title(f"pitch {cam.pitch:.0f}°, yaw {cam.yaw:+.0f}°\nscale {cam.scale:.2f}",
                     fontsize=7)
        ax = axes[1, k]
        uv, used = perturb_proportions(front.project(pose), rng)
        uv = perturb_joints(uv, rng, 0.02)
        draw_2d(ax, front.project(pose), color="tab:blue", alpha=0.35, sides=False)
        draw_2d(ax, uv)
        ax.set_title("legs ×{leg:.2f}, spine ×{spine:.2f}\narms ×{arm:.2f}".format(**used),
                     fontsize=7)
    _share_limits(axes.ravel())
    axes[0, 0].set_ylabel("random views", fontsize=8)
    axes[1, 0].set_ylabel("front view, perturbed\n(blue: true proportions)", fontsize=8)
    fig.set_dpi(FIG_DPI)
    return fig


def alignment_terms(generator, windows, seed=0, tau=0.1):
    """The three terms of Eq. (13) and the cosine-similarity matrices of Eq. (12) for a batch
    of real windows drawn in random views, with the generator's trained 2D encoders:
    ``{"match", "recon", "contrast"}`` floats, ``sim_tr`` / ``sim_k`` (B, B) arrays
    (row i: 3D embedding of window i against the 2D embeddings of all windows)."""
    import torch
    import torch.nn.functional as F

    from physlab.motion.align import alignment_losses, sketch_batch
    from physlab.motion.train import condition_batch

    model = generator.model
    if not getattr(model, "has_sketch_encoders", False):
        raise ValueError(f"{generator.path} has no 2D encoders (train --stage align)")
    rng = np.random.default_rng(seed)
    g = torch.Generator().manual_seed(seed)
    w = np.asarray(windows, dtype=float)
    cond = condition_batch(w, rng)
    sk = sketch_batch(cond, rng)
    feats = torch.tensor(np.stack([generator.stats.normalize(_encode(x, generator))
                                   for x in w]), dtype=torch.float32)
    sched = generator.scheduler
    t = sched.sample_timesteps(len(w), generator=g)
    noise = torch.randn(feats.shape, generator=g)
    x_t = sched.add_noise(feats, noise, t)
    a = torch.tensor(np.stack([generator.text_cache.get("a person walks")] * len(w)),
                     dtype=torch.float32)
    with torch.no_grad():
        terms = alignment_losses(model, x_t, t, a, cond, sk,
                                 sched.training_target(feats, noise, t), tau=tau)
        s3_tr, s3_k = model.condition_embeddings(cond)
        s2_tr, s2_k = model.condition_embeddings({**cond, **sk})

    def sim(a3, a2):
        return (F.normalize(a3, dim=-1) @ F.normalize(a2, dim=-1).T).numpy()

    return {**{k: float(v) for k, v in terms.items()},
            "sim_tr": sim(s3_tr.mean(1), s2_tr.mean(1)), "sim_k": sim(s3_k, s2_k)}


def _encode(x, generator):
    from physlab.motion.features import encode_motion

    return encode_motion(x, generator.config.representation)


def embedding_similarity_figure(terms):
    """The two cosine-similarity matrices of :func:`alignment_terms` side by side: a bright
    diagonal means each 3D condition is nearest to its own drawing (Eq. (12))."""
    fig, axes = new_figure(ncols=2, width=3.0, height=3.0)
    for ax, key, title in zip(axes, ("sim_tr", "sim_k"), ("trajectories", "keyposes")):
        im = ax.imshow(terms[key], vmin=-1, vmax=1, cmap="RdBu_r")
        acc = float(np.mean(np.argmax(terms[key], axis=1) == np.arange(len(terms[key]))))
        ax.set_title(f"{title}: sim(s3D_i, s2D_j)\nown drawing nearest in {acc:.0%} of rows",
                     fontsize=8)
        ax.set_xlabel("2D embedding j", fontsize=7)
        ax.set_ylabel("3D embedding i", fontsize=7)
        ax.tick_params(labelsize=6)
    fig.colorbar(im, ax=list(axes), shrink=0.8).ax.tick_params(labelsize=6)
    fig.set_dpi(FIG_DPI)
    return fig


def guidance_steps(generator, action, sketch, iterations=(0, 5, 10, 20, 40), seed=0, steps=50):
    """The 2D inference guidance step by step: the same sketch generated with 0, 5, 10, ...
    L-BFGS iterations on the final x̂₀ (Eqs. (15)–(16)); returns ``{iters: (joints, 2D error,
    seconds)}`` with the mean projected trajectory error over the drawn frames."""
    out = {}
    for k in iterations:
        tic = time.perf_counter()
        x = generator(action, seed=seed, steps=steps, inference_guidance=0,
                      guidance_final=int(k), **sketch)
        out[int(k)] = (x, trajectory_error_2d(x, sketch), time.perf_counter() - tic)
    return out


def trajectory_error_2d(joints, sketch):
    """Mean distance (normalised units) between the projected trajectory joints and the
    drawn trajectories of a sketch (:func:`~physlab.motion.camera.sketch_kwargs` form)."""
    from physlab.motion.sampling import build_sketch

    sk = build_sketch(sketch.get("keypose_2d"), sketch.get("keypose_at", "first"),
                      sketch.get("trajectories_2d"), sketch["camera"], n_frames=len(joints))
    if not sk["traj_mask"].any():
        return 0.0
    return trajectory_error(sketch["camera"].project(np.asarray(joints)), sk["trajectory"],
                            TRAJECTORY_JOINTS, sk["traj_mask"])


def _overlay(ax, x, sketch):
    """A motion seen from the sketch's camera (blue: every 13th frame, the trajectory joints'
    paths) over the drawing (red: strokes, and the keypose stood under the motion's pelvis at
    the key frame)."""
    uv = sketch["camera"].project(x)
    for f in range(0, len(x), 13):
        draw_2d(ax, uv[f], color="tab:blue", lw=0.9, alpha=0.45, sides=False)
    for name, pts in (sketch.get("trajectories_2d") or {}).items():
        j = JOINT_NAMES.index(name)
        ax.plot(pts[:, 0], pts[:, 1], color="#dc0000", lw=2.0)
        ax.plot(uv[:, j, 0], uv[:, j, 1], color="tab:blue", lw=1.2)
    key = sketch.get("keypose_2d")
    if key is not None:
        kf = 0 if sketch.get("keypose_at", "first") == "first" else len(x) - 1
        draw_2d(ax, key - key[0] + uv[kf, 0], color="#dc0000", lw=1.0, sides=False)


def guidance_steps_figure(result, sketch):
    """Projected pelvis / trajectory joints after each number of guidance iterations, over
    the drawing (red)."""
    ks = list(result)
    fig, axes = new_figure(ncols=len(ks), width=1.7, height=2.4)
    for ax, k in zip(axes, ks):
        x, err, sec = result[k]
        _overlay(ax, x, sketch)
        ax.set_title(f"{k} iterations\nerr {err:.3f}, {sec:.2f} s", fontsize=7)
    _share_limits(axes)
    fig.set_dpi(FIG_DPI)
    return fig


def example_sketch():
    """Lesson 10's starting sketch (:data:`EXAMPLE_SKETCH`)."""
    from physlab.motion.sketch import Sketch

    return Sketch.load(EXAMPLE_SKETCH)


def baselines_comparison(generator, windows, texts, seed=0, steps=50, lifter=None,
                         database=None, noise=0.0):
    """The lesson's small Table 1: each window's random Cross condition drawn in a random
    view, then every method: text only, retrieval (over ``database``: a
    :class:`~physlab.motion.baselines.MotionRetrieval`), lift-and-control (``lifter``) and
    physlab's 2D encoders, each without and with the 2D guidance. Returns ``{method: {"err2d",
    "err3d", "seconds", "joints"}}`` (errors: mean over windows of the projected / 3D
    trajectory error over the drawn frames, plus ``conds``, ``sketches`` and ``cameras``)."""
    from physlab.motion.baselines import lift
    from physlab.motion.evaluate import GUIDED, UNGUIDED, draw_conditions, eval_conditions

    conds = eval_conditions(np.asarray(windows), seed=seed)
    cams, sketches = draw_conditions(conds, seed=seed, noise=noise)
    methods = {"text only": lambda t, k, i: generator(t, seed=seed + i, steps=steps)}
    if database is not None:
        methods["retrieval"] = lambda t, k, i: database(t, **k)
    if lifter is not None:
        def lifted(opts):
            def run(t, k, i):
                k3, t3 = lift(lifter, **k)
                return generator(t, keypose_3d=k3, trajectories_3d=t3, keypose_at=k["keypose_at"],
                                 seed=seed + i, steps=steps, **opts)
            return run
        methods["lift-and-control"] = lifted(UNGUIDED)
        methods["lift-and-control + guidance"] = lifted(GUIDED)
    for suffix, opts in (("", UNGUIDED), (" + guidance", GUIDED)):
        methods["physlab (2D encoders)" + suffix] = (
            lambda t, k, i, opts=opts: generator(t, seed=seed + i, steps=steps, **k, **opts))
    out = {}
    for name, f in methods.items():
        tic = time.perf_counter()
        xs = [f(t, k, i) for i, (t, k) in enumerate(zip(texts, sketches))]
        sec = (time.perf_counter() - tic) / len(xs)
        e2 = [trajectory_error_2d(x, k) for x, k in zip(xs, sketches)]
        e3 = [trajectory_error(x, c.trajectory, TRAJECTORY_JOINTS, c.mask)
              for x, c in zip(xs, conds)]
        out[name] = {"err2d": float(np.mean(e2)), "err3d": float(np.mean(e3)),
                     "seconds": sec, "joints": np.stack(xs)}
    out["conds"], out["sketches"], out["cameras"] = conds, sketches, cams
    return out


def baselines_figure(result, index=None, methods=None):
    """One window's sketch (red) with each method's motion projected in its view (blue);
    ``index`` None: the first window whose drawing has a pelvis stroke (the easiest to read),
    else window 0. Panels share their axes."""
    if index is None:
        index = next((i for i, c in enumerate(result["conds"]) if c.mask[:, 0].any()), 0)
    sketch = result["sketches"][index]
    names = [m for m in (methods or result) if m not in ("conds", "sketches", "cameras")]
    fig, axes = new_figure(ncols=len(names), width=2.0, height=2.9)
    axes = np.atleast_1d(axes)
    for ax, name in zip(axes, names):
        _overlay(ax, result[name]["joints"][index], sketch)
        err = trajectory_error_2d(result[name]["joints"][index], sketch)      # this window
        ax.set_title(name.replace(" + ", "\n+ ") + f"\n2D err {err:.3f}", fontsize=7)
        ax.tick_params(labelsize=6)
    _share_limits(axes)
    fig.suptitle(f"held-out window {index}: the drawing (red) and each method's motion seen "
                 f"from the drawing's view (blue)", fontsize=8)
    fig.set_dpi(FIG_DPI)
    return fig


def write_example_sketch(path=EXAMPLE_SKETCH, seed=0):
    """Write lesson 10's starting sketch: the first pose of a held-out walk, seen from a 3/4
    view (pitch 15°, yaw 30°), drawn as a person would draw it on a 480 × 400 canvas — head
    circle, body line, one stroke per limb, a little hand wobble — and a pelvis stroke that
    goes forward and curves left, drawn at a steady pace (with timestamps)."""
    from physlab.motion.camera import to_pixels
    from physlab.motion.sketch import Sketch, Stroke

    rng = np.random.default_rng(seed)
    cam = Camera(1.0, 15.0, 30.0)
    pose, _ = lesson_window(0)
    uv = cam.project(pose[0])
    origin, ppu = np.array([170.0, 330.0]), 150.0
    px = to_pixels(uv, origin, ppu)

    def wobble(p, n=12):
        p = np.asarray(p, dtype=float)
        s = np.linspace(0, 1, len(p))
        q = np.linspace(0, 1, n * (len(p) - 1) + 1)
        out = np.stack([np.interp(q, s, p[:, k]) for k in range(2)], axis=1)
        return out + rng.normal(0, 0.6, out.shape)

    J = {n: i for i, n in enumerate(JOINT_NAMES)}
    a = np.linspace(0, 2 * np.pi, 32)
    strokes = [Stroke(px[J["head"]] + 13 * np.c_[np.cos(a), np.sin(a)] + [0, -6]),
               Stroke(wobble(px[[J["neck"], J["spine3"], J["spine1"], J["pelvis"]]]))]
    for side in ("left", "right"):
        strokes.append(Stroke(wobble(px[[J[f"{side}_shoulder"], J[f"{side}_elbow"],
                                          J[f"{side}_wrist"]]])))
        strokes.append(Stroke(wobble(px[[J[f"{side}_hip"], J[f"{side}_knee"],
                                          J[f"{side}_ankle"], J[f"{side}_foot"]]])))
    t = np.linspace(0, 1, 40)
    walk = np.stack([0.9 * t + 0.25 * t ** 3, np.zeros_like(t), 1.6 * t - 0.3 * t ** 3],
                    axis=1) + [0.0, pose[0, 0, 1], 0.0]               # forward, curving left
    drawn = wobble(to_pixels(cam.project(walk), origin, ppu)[::3], n=3)
    strokes.append(Stroke(drawn, "trajectory", times=np.linspace(0, 1.6, len(drawn))))
    sk = Sketch(action="a person walks", camera=cam, strokes=strokes, size=(480, 400))
    sk.keypose()
    sk.save(path)
    return Path(path)
