"""PhysAnimator end to end: a drawing becomes a body (mask → outline → Triangle mesh, the
drawing as texture), a scene is simulated (:func:`physlab.physanimator.simulate`) and rendered
frame by frame, and written as GIF/MP4 with the control images — the function behind
``physlab animate``.

Rendering is physlab's honest CPU substitute for the paper's sketch-guided video diffusion
(ToonCrafter + ControlNet, weights not available offline): the drawing is warped by the
simulated mesh (:class:`physlab.render.WarpRenderer`), and the per-frame control images such a
model would consume are produced alongside (:func:`physlab.render.edge_map`); a diffusion
renderer would plug in behind :class:`physlab.render.Renderer`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physlab import datasets
from physlab.mesh import foreground_mask, mesh_from_mask

from . import rigging, scene as _scene, simulation, strokes

__all__ = ["drawing_body", "AnimationResult", "animate", "animate_drawing"]


def _strip(n_frames, n=6):
    """Indices of ``n`` evenly spaced frames out of ``n_frames``."""
    return np.unique(np.linspace(0, n_frames - 1, n).round().astype(int))


def drawing_body(drawing, E=2e5, nu=0.3, rho=1.0, max_area=None, offset=(0.0, 0.0), depth=0.0,
                 mask=None):
    """A :class:`~physlab.physanimator.Body` from a drawing (:class:`physlab.datasets.Drawing`
    or an RGBA image): foreground mask → boundary polygon → Triangle mesh; the drawing is
    the body's texture."""
    image = drawing.image if hasattr(drawing, "image") else np.asarray(drawing)
    name = getattr(drawing, "name", "drawing")
    mask = foreground_mask(image) if mask is None else mask
    mesh = mesh_from_mask(mask, max_area=max_area)
    return _scene.Body(mesh, _scene.Material(E=E, nu=nu, rho=rho), texture=image, offset=offset,
                   depth=depth, name=name)


@dataclass
class AnimationResult:
    """Output of :func:`animate`: the simulation, rendered frames (F, H, W, 3) uint8 and
    control images (F, H, W) uint8 (dark lines on white); ``frame_index`` (F,) which stored
    frames they are."""

    animation: object
    frames: np.ndarray
    controls: np.ndarray | None
    frame_index: np.ndarray | None = None   # stored-frame numbers of ``frames`` (all: None)


def animate(scene, duration=2.0, fps=24, dt=1e-3, control=True, supersample=2, progress=False,
            background=(1.0, 1.0, 1.0), frames=None):
    """Simulate ``scene`` and render every frame by warping each body's texture with its
    simulated mesh (bodies without texture are drawn flat grey). ``frames``: indices of the
    stored frames to render, or a count of evenly spaced ones (default all; a filmstrip needs
    only a few). Returns
    :class:`AnimationResult` (``frame_index``: the rendered frames' indices)."""
    from physlab.render import WarpRenderer

    anim = simulation.simulate(scene, duration, dt=dt, fps=fps, progress=progress)
    textures, X_list = [], []
    for b in scene.bodies:
        if b.texture is None:  # a flat grey texture covering the mesh's bounding box
            lo = np.floor(b.mesh.X.min(0)) - 1
            span = np.ceil(b.mesh.X.max(0) - lo).astype(int) + 2
            textures.append(np.full((span[1], span[0], 4), (150, 150, 160, 255), np.uint8))
            X_list.append(b.mesh.X - lo)
        else:
            textures.append(b.texture)
            X_list.append(b.mesh.X)
    W, H = scene.size
    renderer = WarpRenderer(textures, X_list, [b.mesh.tris for b in scene.bodies], (H, W),
                            depth=[b.depth for b in scene.bodies], background=background,
                            supersample=supersample, control=control)
    if frames is None:
        index = np.arange(anim.n_frames)
    elif np.ndim(frames) == 0:                       # a count: evenly spaced frames
        index = _strip(anim.n_frames, int(frames))
    else:
        index = np.asarray(frames, dtype=int)
        if index.size and (index.min() < 0 or index.max() >= anim.n_frames):
            raise ValueError(f"frames must be indices in 0..{anim.n_frames - 1}, got "
                             f"{index.tolist()}")
    out = renderer.render_sequence([anim.frame(k) for k in index], progress=progress)
    images, controls = out if control else (out, None)
    return AnimationResult(anim, images, controls, index)


def animate_drawing(drawing="tree", duration=2.0, fps=24, E=1.5e5, nu=0.3, strength=4e4,
                    direction_deg=0.0, out="animation.gif", control_out=None, size=256,
                    max_side=512, progress=True):
    """Command-line pipeline (``physlab animate``): a drawing blown by one wind stroke.

    ``drawing``: a sample name ("ball", "tree", "flag", "jelly") or the path of an RGBA/RGB
    image (light background or alpha; larger images are downscaled to ``max_side`` pixels).
    The lowest part of the drawing is pinned; a wind stroke
    crosses its upper third. Writes ``out`` (.gif or .mp4) and optionally the control images
    to ``control_out``. Returns the :class:`AnimationResult`.
    """
    from pathlib import Path

    from physlab.render import frames_to_gif, frames_to_mp4

    if drawing in datasets.SAMPLE_DRAWINGS:
        d = datasets.SAMPLE_DRAWINGS[drawing](size=size)
    else:
        from physlab.image import as_float, read_image, to_uint8

        if not Path(str(drawing)).suffix:
            raise ValueError(f"drawing must be one of {sorted(datasets.SAMPLE_DRAWINGS)} or the "
                             f"path of an image file, got {drawing!r}")
        img = to_uint8(as_float(read_image(drawing, "drawing"), channels=4))   # 8/16-bit, grey
        scale = max_side / max(img.shape[:2])
        if scale < 1:
            import cv2

            img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        rgba = np.ascontiguousarray(img)
        rgba[..., 3] = np.where(foreground_mask(rgba[..., :3]), 255, 0)  # light background → alpha
        d = datasets.Drawing(name=Path(drawing).stem, image=rgba)
    body = drawing_body(d, E=E, nu=nu)
    H, W = d.image.shape[:2]
    X = body.mesh.X
    rigs = [rigging.FixedRig(center=tuple(p), radius=0.05 * H)
            for p in (d.pins if len(d.pins) else X[X[:, 1] >= np.quantile(X[:, 1], 0.98)][:3])]
    th = np.deg2rad(direction_deg)
    c, L = np.array([W / 2, np.quantile(X[:, 1], 0.33)]), 0.8 * max(H, W)
    dirv = np.array([np.cos(th), np.sin(th)])
    stroke = strokes.EnergyStroke([c - L * dirv, c + L * dirv], "wind", strength=strength,
                             range=0.35 * max(H, W), speed=1.2 * max(H, W), n_particles=3, loop=True)
    scene = _scene.Scene([body], strokes=[stroke], rigs=rigs, damping=2.0, size=(W, H))
    result = animate(scene, duration, fps=fps, control=control_out is not None, progress=progress)
    write = frames_to_mp4 if str(out).endswith(".mp4") else frames_to_gif
    write(result.frames, out, fps=fps)
    if control_out is not None:
        write(np.repeat(result.controls[..., None], 3, -1), control_out, fps=fps)
    return result
