"""Frame interpolation between two images: I(α) = F(I0, I1, α) (Brodt & Bessmeltsev 2024, Sec. 5.2).

The paper interpolates each pair ``(I→(t), I←(t))`` with the pretrained RIFE network
[Huang et al. 2022]. RIFE's weights are not available offline, so physlab's honest CPU
substitute is the classical recipe RIFE learned to replace: **dense optical flow in both
directions + backward warping + occlusion-aware blending**. Anything that satisfies the
:class:`FrameInterpolator` protocol (a RIFE wrapper, for instance) plugs in instead.

Conventions
-----------
* Images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` **straight** (non-premultiplied) RGBA, uint8
  or float in ``[0, 1]``; ``(H, W)`` grey is read as RGB. Outputs are float32.
* Pixel ``(row i, column j)`` has centre ``(x, y) = (j, i)``, y down (as in OpenCV).
* A flow ``f`` ``(H, W, 2)`` float32 is in pixels, components ``(x, y)``: the forward flow
  from ``img0`` to ``img1`` maps pixel ``p`` of ``img0`` to ``p + f(p)`` in ``img1``, i.e.
  ``img0(p) ≈ img1(p + f(p))`` (OpenCV's ``calcOpticalFlow*(prev=img0, next=img1)``).

The flow interpolator (:class:`FlowInterpolator`)
-------------------------------------------------
1. *Flow image*: RGBA is composited over white, turned into luminance and darkened inside the
   silhouette by ``silhouette_weight`` (``g = (1 − s) L + s (1 − a)``, so the background stays
   white and a white character still has a visible outline); 8-bit grey.
2. *Bidirectional flow* ``f01``, ``f10`` with OpenCV's DIS [Kroeger et al. 2016] (default) or
   Farnebäck [2003].
3. *Occlusion masks* by forward–backward consistency [Sundaram, Brox & Keutzer 2010, Eq. (5)]:
   pixel ``p`` of ``img0`` has no match in ``img1`` when
   ``|f01(p) + f10(p + f01(p))|² > 0.01 (|f01|² + |f10(p + f01)|²) + 0.5``; likewise for img1.
4. *Flow from the intermediate frame* by the linear-motion approximation of Super SloMo
   [Jiang et al. 2018, Eq. (4)], which uses both flows evaluated at the target pixel ``p``
   (no flow reversal/splatting; exact for translations, approximate at motion boundaries)::

       F_{α→0}(p) = −(1 − α) α f01(p) + α² f10(p)
       F_{α→1}(p) = (1 − α)² f01(p) − α (1 − α) f10(p)

5. *Backward warp* premultiplied colour and alpha with ``cv2.remap`` (bilinear):
   ``W0 = img0(p + F_{α→0}(p))``, ``W1 = img1(p + F_{α→1}(p))``.
6. *Blend* with visibility-weighted weights [Jiang et al. 2018, Eq. (1)]
   ``w0 = (1 − α)(1 − o1)``, ``w1 = α (1 − o0)``, ``I = (w0 W0 + w1 W1) / (w0 + w1)``, where
   ``o0`` is img0's occlusion mask sampled where W0 was sampled (that content disappears
   before img1, so img1 cannot supply it) and ``o1`` likewise; where both weights vanish the
   plain ``(1 − α, α)`` is used. The result is un-premultiplied to straight RGBA.

``α = 0`` and ``α = 1`` return the two inputs exactly (as float32).
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import cv2
import numpy as np

from physlab.image import as_float, over_white  # noqa: F401 - over_white re-exported

__all__ = [
    "FrameInterpolator", "FlowInterpolator", "CrossDissolve",
    "as_image", "over_white", "flow_image",
]

_LUMA = np.array([0.2125, 0.7154, 0.0721], np.float32)  # Rec. 709, as skimage.color.rgb2gray
_DIS_PRESETS = {
    "ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
    "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
    "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM,
}
#: Alpha below which a pixel's straight colour is undefined (set to 0 after un-premultiplying).
ALPHA_EPS = 1e-6
_VIS_EPS = 1e-3   # floor of the visibility weights, so (w0, w1) -> (1 − α, α) where both vanish


# --------------------------------------------------------------------------- image helpers
def as_image(img, name="image"):
    """Validate an image and return it as float32 in [0, 1].

    Parameters
    ----------
    img : (H, W), (H, W, 3) or (H, W, 4) array, uint8, uint16 or float in [0, 1]; RGBA is
        straight.
    name : str, used in error messages.

    Returns
    -------
    (H, W, C) float32, C = 3 (grey and RGB) or 4 (RGBA) — :func:`physlab.image.as_float`.

    Raises
    ------
    ValueError for other shapes, NaN/inf, floats outside [0, 1], other dtypes.
    """
    return as_float(img, name, channels=3)


def flow_image(img, silhouette_weight=0.25):
    """The 8-bit grey image optical flow is computed on.

    ``g = (1 − s)·L + s·(1 − a)`` with ``L`` the Rec. 709 luminance over white and ``a`` the
    alpha: the background stays white (``g = 1``) and the inside of the silhouette is darkened
    by ``s``, so even a white-on-transparent character has a visible outline to track.

    Parameters
    ----------
    img : (H, W, 3|4) float32 in [0, 1].
    silhouette_weight : float in [0, 1], ``s`` (ignored for RGB).

    Returns
    -------
    (H, W) uint8.
    """
    L = over_white(img) @ _LUMA
    if img.shape[-1] == 4 and silhouette_weight:
        L = (1.0 - silhouette_weight) * L + silhouette_weight * (1.0 - img[..., 3])
    return np.clip(L * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _check_pair(img0, img1):
    a = as_image(img0, "img0")
    b = as_image(img1, "img1")
    if a.shape != b.shape:
        raise ValueError(f"img0 and img1 must have the same shape, got {a.shape} and {b.shape} "
                         f"(resize/pad both to one canvas, and give both or neither an alpha "
                         f"channel)")
    return a, b


def _check_alphas(alphas):
    al = np.asarray(alphas, dtype=np.float64)
    if al.ndim == 0:
        al = al[None]
    if al.ndim != 1:
        raise ValueError(f"alphas must be a scalar or 1-D array, got shape {al.shape}")
    if not np.isfinite(al).all():
        raise ValueError("alphas contain NaN or inf")
    if al.size and (al.min() < 0.0 or al.max() > 1.0):
        raise ValueError(f"alphas must lie in [0, 1], got range [{al.min():g}, {al.max():g}]")
    return al


def _premultiply(img):
    """(H, W, 4) straight -> premultiplied (copy); RGB is returned as is."""
    if img.shape[-1] == 3:
        return img
    p = img.copy()
    p[..., :3] *= img[..., 3:4]
    return p


def _unpremultiply(p):
    """(..., 4) premultiplied -> straight RGBA (in place); colour 0 where alpha ≤ ALPHA_EPS."""
    if p.shape[-1] == 4:
        a = p[..., 3:4]
        p[..., :3] *= np.where(a > ALPHA_EPS, 1.0 / np.maximum(a, ALPHA_EPS), 0.0)
    return np.clip(p, 0.0, 1.0, out=p)


def _unpremultiply_frame(p):
    """(H, W, C) float32 premultiplied -> straight, in place; the fast single-frame path."""
    if p.shape[-1] == 4:
        a = cv2.extractChannel(p, 3)
        inv = cv2.divide(1.0, a)                                     # 1/a, 0 where a == 0
        inv[a <= ALPHA_EPS] = 0.0
        cv2.multiply(p, cv2.merge([inv, inv, inv, np.ones_like(inv)]), dst=p)
    return np.clip(p, 0.0, 1.0, out=p)


def _check_out(out, shape):
    if out is None:
        return np.empty(shape, np.float32)
    if not isinstance(out, np.ndarray) or out.shape != tuple(shape) or out.dtype != np.float32:
        raise ValueError(f"out must be a float32 array of shape {tuple(shape)}, got "
                         f"{getattr(out, 'dtype', type(out))} {np.shape(out)}")
    return out


# --------------------------------------------------------------------------- protocol
@runtime_checkable
class FrameInterpolator(Protocol):
    """What :func:`physlab.inbetween.blend.image_matrix` needs from an interpolator.

    ``__call__(img0, img1, alphas)`` → ``(len(alphas), H, W, C)`` float32 frames with
    frame(α=0) = img0 and frame(α=1) = img1 exactly (``C`` as the inputs, straight RGBA).

    ``flow(img0, img1)`` → ``(H, W, 2)`` float32 forward flow in pixels ``(x, y)`` from img0
    to img1, ``img0(p) ≈ img1(p + flow(p))`` — the ``v(t)`` of the paper's Q(t).

    Optional: ``interpolate_and_flow(img0, img1, alphas, out=None)`` → ``(frames, flow)``;
    when present ``image_matrix`` uses it (a row then costs one flow estimate less, and
    ``out=`` lets the frames go straight into the matrix). A RIFE wrapper would return its
    intermediate flow here.
    """

    def __call__(self, img0, img1, alphas) -> np.ndarray: ...

    def flow(self, img0, img1) -> np.ndarray: ...


# --------------------------------------------------------------------------- cross-dissolve
class CrossDissolve:
    """``I(α) = (1 − α) img0 + α img1`` in premultiplied colour; no motion (flow ≡ 0).

    The baseline every motion-compensated interpolator must beat, and a cheap stand-in in
    tests.
    """

    def __repr__(self):
        return "CrossDissolve()"

    def __call__(self, img0, img1, alphas):
        """(n_α, H, W, C) float32 frames; see :class:`FrameInterpolator`."""
        a, b = _check_pair(img0, img1)
        al = _check_alphas(alphas)
        pa, pb = _premultiply(a), _premultiply(b)
        w = al.astype(np.float32)[:, None, None, None]
        out = _unpremultiply((1.0 - w) * pa + w * pb)                # (n_α, H, W, C)
        out[al == 0.0] = a
        out[al == 1.0] = b
        return out

    def flow(self, img0, img1):
        """(H, W, 2) float32 zeros (after validating the pair)."""
        a, _ = _check_pair(img0, img1)
        return np.zeros(a.shape[:2] + (2,), np.float32)

    def interpolate_and_flow(self, img0, img1, alphas, out=None):
        """``(frames, zero flow)``; frames written into ``out`` when given."""
        frames = self(img0, img1, alphas)
        if out is not None:
            out = _check_out(out, frames.shape)
            out[...] = frames
            frames = out
        return frames, self.flow(img0, img1)


# --------------------------------------------------------------------------- flow interpolator
class FlowInterpolator:
    """Bidirectional optical flow + backward warping + occlusion-aware blending.

    physlab's CPU substitute for RIFE (Brodt & Bessmeltsev 2024, Sec. 5.2); the algorithm is
    described in the module docstring. One call with a whole row of α values estimates the two
    flows once (``flow_pair``) and then only warps (``interpolate_with_flows``).

    Parameters
    ----------
    method : "dis" (default; Kroeger et al. 2016) or "farneback" (Farnebäck 2003).
    preset : DIS preset, "ultrafast", "fast" or "medium" (default "medium"; OpenCV has no
        "fine"). On 512² images "medium" costs ≈ 30 ms per flow against ≈ 6 ms for "fast",
        and is clearly more accurate on textured drawings (see tests/inbetween).
    silhouette_weight : float in [0, 1], darkening of the silhouette in :func:`flow_image`.
    occlusion : bool, use forward–backward occlusion masks in the blend (default True).
    fb_rel, fb_abs : floats, the consistency test ``|f01 + f10∘(id + f01)|² > fb_rel
        (|f01|² + |f10∘(id+f01)|²) + fb_abs`` (px², Sundaram et al. 2010 use 0.01 and 0.5).
    farneback : dict of keyword overrides for ``cv2.calcOpticalFlowFarneback``.
    """

    def __init__(self, method="dis", preset="medium", silhouette_weight=0.25, occlusion=True,
                 fb_rel=0.01, fb_abs=0.5, farneback=None):
        if method not in ("dis", "farneback"):
            raise ValueError(f"method must be 'dis' or 'farneback', got {method!r}")
        if method == "dis" and preset not in _DIS_PRESETS:
            raise ValueError(f"preset must be one of {sorted(_DIS_PRESETS)}, got {preset!r}")
        if not 0.0 <= silhouette_weight <= 1.0:
            raise ValueError(f"silhouette_weight must be in [0, 1], got {silhouette_weight}")
        if fb_rel < 0 or fb_abs < 0:
            raise ValueError(f"fb_rel and fb_abs must be ≥ 0, got {fb_rel}, {fb_abs}")
        self.method = method
        self.preset = preset
        self.silhouette_weight = float(silhouette_weight)
        self.occlusion = bool(occlusion)
        self.fb_rel = float(fb_rel)
        self.fb_abs = float(fb_abs)
        self.farneback = {"pyr_scale": 0.5, "levels": 5, "winsize": 15, "iterations": 3,
                          "poly_n": 5, "poly_sigma": 1.2, "flags": 0}
        self.farneback.update(farneback or {})

    def __repr__(self):
        return (f"FlowInterpolator(method={self.method!r}, preset={self.preset!r}, "
                f"occlusion={self.occlusion})")

    # ---- flow
    def _flow_grey(self, g0, g1):
        """(H, W) uint8 pair -> (H, W, 2) float32 flow g0 -> g1."""
        if self.method == "dis":
            dis = cv2.DISOpticalFlow_create(_DIS_PRESETS[self.preset])  # fresh: no hidden state
            return dis.calc(g0, g1, None)
        return cv2.calcOpticalFlowFarneback(g0, g1, None, **self.farneback)

    def flow(self, img0, img1):
        """Forward flow img0 → img1.

        Parameters
        ----------
        img0, img1 : (H, W, 3|4) images, same shape.

        Returns
        -------
        (H, W, 2) float32, pixels ``(x, y)``: ``img0(p) ≈ img1(p + flow(p))``.
        """
        a, b = _check_pair(img0, img1)
        s = self.silhouette_weight
        return self._flow_grey(flow_image(a, s), flow_image(b, s))

    def flow_pair(self, img0, img1):
        """Both flows ``(f01, f10)``, each (H, W, 2) float32 in pixels (two estimates)."""
        a, b = _check_pair(img0, img1)
        s = self.silhouette_weight
        g0, g1 = flow_image(a, s), flow_image(b, s)
        return self._flow_grey(g0, g1), self._flow_grey(g1, g0)

    # ---- warping
    def occlusion_masks(self, f01, f10):
        """Forward–backward inconsistency masks (Sundaram et al. 2010, Eq. (5)).

        Parameters
        ----------
        f01, f10 : (H, W, 2) float32 flows img0 → img1 and img1 → img0, pixels.

        Returns
        -------
        o0, o1 : (H, W) float32 in {0, 1}; ``o0(p) = 1`` when pixel p of img0 has no
        consistent match in img1 (it is occluded or leaves the frame), ``o1`` likewise.
        """
        H, W = f01.shape[:2]
        G = np.dstack(np.meshgrid(np.arange(W, dtype=np.float32),
                                  np.arange(H, dtype=np.float32)))     # (H, W, 2)
        out = []
        for fa, fb in ((f01, f10), (f10, f01)):
            fb_at = cv2.remap(fb, G + fa, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            err = np.sum((fa + fb_at) ** 2, axis=-1)
            bound = self.fb_rel * (np.sum(fa ** 2, -1) + np.sum(fb_at ** 2, -1)) + self.fb_abs
            out.append((err > bound).astype(np.float32))
        return out[0], out[1]

    def interpolate_with_flows(self, img0, img1, alphas, f01, f10, out=None):
        """Frames at ``alphas`` from precomputed flows (no flow estimation).

        Parameters
        ----------
        img0, img1 : (H, W, C) images, C = 3 or 4 (straight RGBA).
        alphas : (n_α,) floats in [0, 1].
        f01, f10 : (H, W, 2) flows img0 → img1 and img1 → img0 (pixels, ``(x, y)``).
        out : optional (n_α, H, W, C) float32 array to write into (saves a copy).

        Returns
        -------
        (n_α, H, W, C) float32, straight RGBA / RGB in [0, 1] (``out`` if given).
        """
        a, b = _check_pair(img0, img1)
        al = _check_alphas(alphas)
        H, W, _ = a.shape
        f01 = self._check_flow(f01, (H, W), "f01")
        f10 = self._check_flow(f10, (H, W), "f10")
        return self._frames(a, b, al, f01, f10, out)

    def _frames(self, a, b, al, f01, f10, out=None):
        """Validated inputs -> (n_α, H, W, C) float32."""
        H, W, C = a.shape
        if self.occlusion:
            o0, o1 = self.occlusion_masks(f01, f10)
        pa, pb = _premultiply(a), _premultiply(b)
        G = np.dstack(np.meshgrid(np.arange(W, dtype=np.float32),
                                  np.arange(H, dtype=np.float32)))     # (H, W, 2) pixel (x, y)
        out = _check_out(out, (len(al), H, W, C))                     # (n_α, H, W, C)
        # per-frame work buffers (reused: fresh 4 MB temporaries cost page faults at 512²)
        m0, m1 = np.empty_like(G), np.empty_like(G)
        W0, W1 = np.empty_like(pa), np.empty_like(pa)
        v0, v1 = np.empty((H, W), np.float32), np.empty((H, W), np.float32)
        for k, alpha in enumerate(al.tolist()):             # python floats: stay float32
            if alpha == 0.0:
                out[k] = a
                continue
            if alpha == 1.0:
                out[k] = b
                continue
            # Jiang et al. 2018 Eq. (4): flows from the intermediate frame, as remap maps
            cv2.scaleAdd(f01, -(1 - alpha) * alpha, G, dst=m0)
            cv2.scaleAdd(f10, alpha * alpha, m0, dst=m0)
            cv2.scaleAdd(f01, (1 - alpha) ** 2, G, dst=m1)
            cv2.scaleAdd(f10, -alpha * (1 - alpha), m1, dst=m1)
            cv2.remap(pa, m0, None, cv2.INTER_LINEAR, dst=W0, borderMode=cv2.BORDER_REPLICATE)
            cv2.remap(pb, m1, None, cv2.INTER_LINEAR, dst=W1, borderMode=cv2.BORDER_REPLICATE)
            frame = out[k]
            np.subtract(W0, W1, out=W0)
            if self.occlusion:
                # visibility: img0's sample is unusable where img1's content is new (o1 at the
                # img1 sample point) and vice versa; +δ falls back to (1 − α, α) where both vanish
                cv2.remap(o1, m1, None, cv2.INTER_LINEAR, dst=v0, borderMode=cv2.BORDER_REPLICATE)
                cv2.remap(o0, m0, None, cv2.INTER_LINEAR, dst=v1, borderMode=cv2.BORDER_REPLICATE)
                np.subtract(1.0 + _VIS_EPS, v0, out=v0)
                np.subtract(1.0 + _VIS_EPS, v1, out=v1)
                v0 *= 1 - alpha                                         # w0
                v1 *= alpha                                             # w1
                v1 += v0
                np.divide(v0, v1, out=v0)                               # w0 / (w0 + w1)
                cv2.multiply(W0, cv2.merge([v0] * C), dst=W0)
            else:
                W0 *= 1 - alpha
            np.add(W1, W0, out=frame)                                   # Jiang et al. Eq. (1)
            _unpremultiply_frame(frame)
        return out

    @staticmethod
    def _check_flow(f, hw, name):
        f = np.asarray(f, dtype=np.float32)
        if f.shape != tuple(hw) + (2,):
            raise ValueError(f"{name} must have shape {tuple(hw) + (2,)}, got {f.shape}")
        if not np.isfinite(f).all():
            raise ValueError(f"{name} contains NaN or inf")
        return f

    # ---- protocol
    def interpolate_and_flow(self, img0, img1, alphas, out=None):
        """``(frames (n_α, H, W, C), f01 (H, W, 2))`` with two flow estimates in all.

        ``out`` : optional (n_α, H, W, C) float32 array the frames are written into.
        """
        a, b = _check_pair(img0, img1)
        al = _check_alphas(alphas)
        s = self.silhouette_weight
        g0, g1 = flow_image(a, s), flow_image(b, s)
        f01, f10 = self._flow_grey(g0, g1), self._flow_grey(g1, g0)
        return self._frames(a, b, al, f01, f10, out), f01

    def __call__(self, img0, img1, alphas):
        """(n_α, H, W, C) float32 frames; see :class:`FrameInterpolator`."""
        return self.interpolate_and_flow(img0, img1, alphas)[0]
