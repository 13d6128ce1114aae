"""An occlusion annotation widget for JupyterLab: paint or outline the occlusion regions of a
keyframe, click its T-junctions, set the depth of the joints near each region, and see the
visible (blue) and hidden (red) contours the layered template chooses (Brodt & Bessmeltsev
2024, Secs. 4–4.4, Figs. 6 and 8; lesson 07).

The paper's user gives, per keyframe, occlusion masks (predicted by a network there; here
:func:`~physlab.inbetween.occlusion.suggest_occlusions` offers a start), the T-junctions where
one drawn outline ends against another (Fig. 7), and a depth order of the joints near the
occlusions (Sec. 5.1). This widget collects exactly those inputs —
:attr:`OcclusionAnnotator.occlusions` (a list of :class:`~physlab.inbetween.occlusion.Occlusion`)
and :attr:`OcclusionAnnotator.skeleton` (the skeleton with ``depth``) — and saves them as one
JSON file that :func:`~physlab.inbetween.occlusion.load_occlusions` also reads; all the
geometry lives in :mod:`physlab.inbetween.occlusion`.

Built on **ipycanvas** like :mod:`~physlab.viz.sketch_canvas` (three layers: the keyframe, the
semi-transparent region masks, and the marks — skeleton, region outlines, T-junctions, the
polygon being drawn, the solved contours). The canvas shows the drawing (the keyframe cropped
to it, ``crop=True``) enlarged by an integer ``scale``; the mouse handlers
:meth:`OcclusionAnnotator._on_down`, ``_on_move`` and ``_on_up`` take canvas pixels, every
other method takes keyframe pixels ``(x, y)`` (pixel ``[i, j]`` centred at ``(j, i)``, y down).

Modes (toggle buttons): **paint** and **erase** (a brush of ``brush px`` on the current
region's mask), **polygon** (clicks add corners, *Close polygon* makes them a new region),
**t-junction** (a click adds a T-junction to the region whose outline is nearest, snapped onto
that outline when within :data:`~physlab.inbetween.occlusion.T_JUNCTION_TOLERANCE` px; a click
on an existing T-junction removes it). Buttons: New region, Delete region, Suggest, Close
polygon, Solve (when a ``target_skeleton`` is given: builds the layered template, draws each
region's outline blue where visible and red where hidden, lists the energies of the
assignments), Save / Load (JSON).
"""
from __future__ import annotations

import html
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from physlab._check import number
from physlab.inbetween.occlusion import (T_JUNCTION_TOLERANCE, Occlusion, _insert_on_outline,
                                         build_layered_template, load_occlusions,
                                         suggest_occlusions)
from physlab.inbetween.skeleton import check_compatible
from physlab.inbetween.template import keyframe_mask
from physlab.viz.canvas_widget import CanvasWidget

__all__ = ["OcclusionAnnotator", "COLORS", "MODES"]

#: Interaction modes, in the order of the toggle buttons.
MODES = ("paint", "erase", "polygon", "t-junction")
#: Colours: region masks (RGB + alpha 0–255: other regions, the current one), outlines, marks
#: (CSS), and the solved contours as in Figs. 6 / 8 (visible blue, hidden red).
COLORS = {"mask": (60, 120, 255, 80), "current": (0, 70, 255, 130),
          "outline": "#1d4fd8", "t_junction": "#ffd400", "t_junction_edge": "#5a4a00",
          "bone": "rgba(25, 25, 25, 0.8)", "joint": "#444444", "near": "#ff7f0e",
          "far": "#9467bd", "selected": "#d6008f", "polygon": "#ff6a00",
          "visible": "#0040ff", "hidden": "#e8000b", "brush": "rgba(0, 70, 255, 0.35)",
          "eraser": "rgba(255, 255, 255, 0.55)"}
#: A click this close (canvas px) to a T-junction removes it.
PICK_PX = 10.0
#: The canvas shows the keyframe enlarged to about this many pixels (integer factor >= 1).
CANVAS_TARGET_PX = 480


@dataclass
class _Region:
    """One editable region: its mask (H, W) bool, T-junctions [(x, y), ...], label."""

    mask: np.ndarray
    t_junctions: list = field(default_factory=list)
    label: str = ""

    def occlusion(self):
        return Occlusion(self.mask, np.asarray(self.t_junctions, float).reshape(-1, 2),
                         self.label)


def _stamp(mask, p0, p1, radius, value):
    """Set the pixels of ``mask`` (H, W) within ``radius`` px of the segment p0–p1 (pixel
    centres, x right, y down) to ``value``, in place; returns how many changed."""
    H, W = mask.shape
    lo = np.floor(np.minimum(p0, p1) - radius).astype(int)
    hi = np.ceil(np.maximum(p0, p1) + radius).astype(int) + 1
    x0, y0 = max(lo[0], 0), max(lo[1], 0)
    x1, y1 = min(hi[0], W), min(hi[1], H)
    if x0 >= x1 or y0 >= y1:
        return 0
    yy, xx = np.mgrid[y0:y1, x0:x1]
    P = np.stack([xx, yy], axis=-1).astype(float)
    ab = p1 - p0
    t = np.clip(((P - p0) @ ab) / max(ab @ ab, 1e-12), 0.0, 1.0)
    hit = np.linalg.norm(P - (p0 + t[..., None] * ab), axis=-1) <= radius
    window = mask[y0:y1, x0:x1]
    changed = int(np.count_nonzero(window[hit] != value))
    window[hit] = value
    return changed


def _outline(mask):
    """(k, 2) outline polygon of a mask's largest component (as saved in JSON)."""
    from physlab.mesh import boundary_polygon

    return boundary_polygon(mask, epsilon=0.5)


class OcclusionAnnotator(CanvasWidget):
    """Annotate a keyframe's occlusions in JupyterLab (``a = OcclusionAnnotator(...); a``).

    Parameters
    ----------
    image : (H, W, 3|4) uint8 or float in [0, 1], the keyframe.
    skeleton : :class:`~physlab.inbetween.skeleton.Skeleton` of the keyframe (pixels); its
        ``depth``, when set, is the starting depth of the joints.
    occlusions : list of :class:`~physlab.inbetween.occlusion.Occlusion` to start from (masks
        of the image's size or polygons), or None.
    target_skeleton : Skeleton of the same topology (e.g. the other key's) into which Solve
        deforms the layered template to choose each region's topology; None hides Solve.
    suggest : bool, start from :func:`~physlab.inbetween.occlusion.suggest_occlusions` when
        ``occlusions`` is None.
    scale : int >= 1 or None, canvas pixels per keyframe pixel (default: the view enlarged to
        about :data:`CANVAS_TARGET_PX`).
    crop : bool, show only the drawing (the bounding box of the foreground, the joints and the
        given regions, plus a margin) rather than the whole keyframe.
    near_px : float > 0 or None, joints within this distance (keyframe px) of the current
        region are offered in the depth control (default ``max(8, 0.08 max(H, W))``).
    file : str, the path in the file box (Save / Load).
    solve_options : dict of extra keywords for
        :func:`~physlab.inbetween.occlusion.build_layered_template` (e.g. ``other_image``,
        ``other_occlusions`` to texture the back layers from the other key).

    Attributes
    ----------
    widget : the ipywidgets box (the annotator also displays itself).
    template : the :class:`~physlab.inbetween.occlusion.LayeredTemplate` of the last Solve, or
        None (any edit clears it).
    occlusions, skeleton, status, current : properties (below).

    Raises
    ------
    TypeError / ValueError naming the argument: an image that is not an image, a skeleton
    whose joints lie outside it, occlusion masks of another size, a target skeleton of another
    topology, a bad ``scale`` or ``near_px``.
    """

    shown_errors = (Exception,)     # a widget's error belongs in its readout, whatever it is

    def __init__(self, image, skeleton, occlusions=None, target_skeleton=None, suggest=True,
                 scale=None, crop=True, near_px=None, file="occlusions.json",
                 solve_options=None):
        import ipywidgets as w
        from ipycanvas import MultiCanvas

        from physlab.image import over_white, to_uint8

        self.image, self.foreground, _ = keyframe_mask(image, skeleton, name="image")
        H, W = self.image.shape[:2]
        self._base = skeleton
        if target_skeleton is not None:
            check_compatible(skeleton, target_skeleton, ("skeleton", "target_skeleton"))
        self.target_skeleton = target_skeleton
        self.near_px = (max(8.0, 0.08 * max(H, W)) if near_px is None
                        else number(near_px, "near_px", lo=0, lo_open=True))
        if solve_options is not None and not isinstance(solve_options, dict):
            raise TypeError(f"solve_options must be a dict of keywords for "
                            f"build_layered_template, got {type(solve_options).__name__}")
        self.solve_options = dict(solve_options or {})
        self._depth = None if skeleton.depth is None else np.array(skeleton.depth, float)
        self.regions, self.template = [], None
        self._current, self._stroke, self._polygon, self._syncing = None, None, [], False
        self._stroke_changed = 0     # pixels the brush stroke in progress changed
        if occlusions is not None:
            if isinstance(occlusions, Occlusion) or not hasattr(occlusions, "__iter__"):
                raise TypeError("occlusions must be a list of Occlusion (or None)")
            for i, o in enumerate(occlusions):
                self._append(o, f"occlusions[{i}]")
        elif suggest:
            for o in suggest_occlusions(self.image, skeleton, mask=self.foreground):
                self._append(o, "a suggested occlusion")

        x0, y0, x1, y1 = self.view = self._view(crop)
        self.scale = s = (max(1, round(CANVAS_TARGET_PX / max(x1 - x0, y1 - y0)))
                          if scale is None else number(scale, "scale", lo=1, integer=True))
        self.canvas = MultiCanvas(3, width=(x1 - x0) * s, height=(y1 - y0) * s)
        self.canvas.layout.border = "1px solid #bbb"    # layers: 0 image, 1 masks, 2 marks
        self.canvas.layout.min_width = f"{(x1 - x0) * s}px"
        bw, box = {"button_width": "86px"}, w.Layout(width="370px")
        self.mode = w.ToggleButtons(options=list(MODES), value="paint", style=bw,
                                    tooltips=["brush adds to the region", "brush removes",
                                              "click corners, then Close polygon",
                                              "click on an outline to add, on a dot to remove"])
        self.brush = w.IntSlider(value=max(2, round(0.02 * max(H, W))), min=1,
                                 max=max(20, round(0.1 * max(H, W))), description="brush px",
                                 continuous_update=False)
        self.region = w.Dropdown(description="region", layout=box)
        self.new = w.Button(description="New region")
        self.delete = w.Button(description="Delete region")
        self.suggest_button = w.Button(description="Suggest",
                                       tooltip="add the regions suggested from the skeleton")
        self.close = w.Button(description="Close polygon")
        self.joint = w.Dropdown(description="joint", layout=box,
                                tooltip="joints near the current region")
        self.depth = w.FloatSlider(value=0.0, min=-3.0, max=3.0, step=0.1, readout_format=".1f",
                                   description="depth", continuous_update=False, layout=box,
                                   tooltip="the joint's depth: smaller = nearer")
        self.solve_button = w.Button(description="Solve", button_style="primary",
                                     tooltip="build the layered template, colour the contours",
                                     layout=w.Layout(display=None if target_skeleton is not None
                                                     else "none"))
        self.file = w.Text(value=str(file), description="file", layout=box)
        self.save_button = w.Button(description="Save")
        self.load_button = w.Button(description="Load")
        self.readout = w.HTML(layout=box)
        self.readout.add_class("physlab-readout")
        self.energies = w.HTML()
        self._on_clicks(((self.new, self.new_region), (self.delete, self.delete_region),
                         (self.suggest_button, self.suggest), (self.close, self.close_polygon),
                         (self.solve_button, self.solve), (self.save_button, self.save),
                         (self.load_button, self.load)))
        self.mode.observe(lambda c: self._guard(self._on_mode, c["old"]), names="value")
        self.region.observe(lambda c: self._guard(self._on_region, c["new"]), names="value")
        self.joint.observe(lambda _c: self._guard(self._sync_depth_slider), names="value")
        self.depth.observe(lambda c: self._guard(self._on_depth, c["new"]), names="value")
        self._route_mouse(self.canvas, self._on_down, self._on_move, self._on_up)
        controls = w.VBox([self.mode, self.brush, self.region,
                           w.HBox([self.new, self.delete]), w.HBox([self.suggest_button,
                                                                   self.close]),
                           self.joint, self.depth, self.solve_button, self.file,
                           w.HBox([self.save_button, self.load_button]), self.readout],
                          layout=w.Layout(margin="0 0 0 12px"))
        self.widget = w.VBox([w.HBox([self.canvas, controls]), self.energies])
        self.widget.add_class("physlab-occlusion-annotator")
        rgb = self._zoom(to_uint8(over_white(self.image)))

        def draw_all():                      # also when a new view of the widget connects
            self.canvas[0].put_image_data(rgb, 0, 0)
            self.redraw()

        self.canvas.on_client_ready(lambda: self._guard(draw_all))
        self.canvas[0].put_image_data(rgb, 0, 0)
        self._select(len(self.regions) - 1 if self.regions else None)
        how = "given" if occlusions is not None else "suggested" if suggest else "yet"
        self._say(f"{len(self.regions)} region(s) {how}; paint or outline occlusions, click "
                  "T-junctions, set the depth of the joints near them")

    # ------------------------------------------------------------------ public state
    @property
    def current(self):
        """Index of the current region (the one painted, listed in the depth control), or
        None."""
        return self._current

    @property
    def occlusions(self):
        """The annotation as a list of :class:`~physlab.inbetween.occlusion.Occlusion`
        (masks (H, W) bool, T-junctions (m, 2), labels); empty regions are left out."""
        return [r.occlusion() for r in self.regions if r.mask.any()]

    @property
    def skeleton(self):
        """The keyframe's :class:`~physlab.inbetween.skeleton.Skeleton` with the annotated
        joint depths (smaller = nearer; the given skeleton unchanged when no depth is set)."""
        return self._base if self._depth is None else self._base.with_depth(
            self._depth.copy())               # Skeleton freezes the array it is given

    # ------------------------------------------------------------------ coordinates
    def to_canvas(self, points):
        """Keyframe pixels ``(..., 2)`` → canvas pixels (the centre of the enlarged pixel)."""
        return (np.asarray(points, dtype=float) - self.view[:2] + 0.5) * self.scale

    def to_image(self, x, y):
        """Canvas pixels → keyframe pixels, (2,) float."""
        return np.array([x, y], dtype=float) / self.scale - 0.5 + self.view[:2]

    def _view(self, crop):
        """``(x0, y0, x1, y1)`` keyframe pixels the canvas shows: everything, or the bounding
        box of the foreground, the joints and the regions plus a margin."""
        H, W = self.image.shape[:2]
        if not crop:
            return np.array([0, 0, W, H])
        ys, xs = np.nonzero(np.any([self.foreground] + [r.mask for r in self.regions], axis=0))
        xy = self._base.xy
        lo = np.minimum([xs.min(), ys.min()], np.floor(xy.min(axis=0)))
        hi = np.maximum([xs.max(), ys.max()], np.ceil(xy.max(axis=0))) + 1
        m = max(4, round(0.05 * max(H, W)))
        return np.array([max(lo[0] - m, 0), max(lo[1] - m, 0), min(hi[0] + m, W),
                         min(hi[1] + m, H)], dtype=int)

    def _zoom(self, img):
        """The viewed part of a keyframe-sized image, enlarged ``scale`` times."""
        x0, y0, x1, y1 = self.view
        s = self.scale
        return np.repeat(np.repeat(img[y0:y1, x0:x1], s, axis=0), s, axis=1)

    # ------------------------------------------------------------------ regions
    def _append(self, occlusion, where):
        if not isinstance(occlusion, Occlusion):
            raise TypeError(f"{where} is a {type(occlusion).__name__}, not an Occlusion")
        H, W = self.image.shape[:2]
        try:
            mask = occlusion.mask_array((H, W)).copy()
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None
        if not mask.any():
            raise ValueError(f"{where} covers no pixel of the {W}x{H} image (is it the "
                             "annotation of another keyframe?)")
        self.regions.append(_Region(mask, [np.array(p, float) for p in occlusion.t_junctions],
                                    occlusion.label))

    def add_region(self, mask, t_junctions=(), label=""):
        """Add a region (mask (H, W) bool or polygon (k, 2) keyframe px) and make it current;
        returns its index."""
        self._append(Occlusion(mask, t_junctions, label), "the region")
        self._select(len(self.regions) - 1)
        self._changed()
        return len(self.regions) - 1

    def new_region(self, label=""):
        """Start an empty region, make it current and switch to paint mode; returns its
        index."""
        H, W = self.image.shape[:2]
        self.regions.append(_Region(np.zeros((H, W), bool), [], str(label)))
        self._select(len(self.regions) - 1)
        self.mode.value = "paint"
        self._say(f"region {self._current}: paint it (brush) or outline it (polygon)")
        return self._current

    def delete_region(self, index=None):
        """Remove region ``index`` (default: the current one)."""
        i = self._index(index)
        del self.regions[i]
        self._select(min(i, len(self.regions) - 1) if self.regions else None)
        self._changed()
        self._say(f"deleted region {i}; {len(self.regions)} left")

    def select_region(self, index):
        """Make region ``index`` current."""
        self._select(self._index(index))

    def suggest(self):
        """Add the regions :func:`~physlab.inbetween.occlusion.suggest_occlusions` finds from
        the skeleton (capsules of non-adjacent bones overlapping in 2D)."""
        found = suggest_occlusions(self.image, self._base, mask=self.foreground)
        for o in found:
            self._append(o, "a suggested occlusion")
        if found:
            self._select(len(self.regions) - 1)
            self._changed()
        self._say(f"{len(found)} suggested region(s) added" if found else
                  "no limbs overlap in 2D: nothing to suggest")

    def _index(self, index):
        if index is None:
            if self._current is None:
                raise ValueError("no region yet: press New region, draw a polygon or Suggest")
            return self._current
        i = number(index, "region index", integer=True)
        if not 0 <= i < len(self.regions):
            raise ValueError(f"region index must be in 0..{len(self.regions) - 1}, got {index}")
        return i

    def _select(self, i):
        self._current = i
        self._syncing = True
        try:
            self.region.options = [(f"{k}: {r.label or 'region'}", k)
                                   for k, r in enumerate(self.regions)]
            self.region.value = i
        finally:
            self._syncing = False
        self._update_joints()
        self.redraw()

    def _on_region(self, i):
        if not self._syncing and i is not None and i != self._current:
            self._current = i
            self._update_joints()
            self.redraw()

    def _changed(self):
        """The annotation changed: the solved template no longer describes it."""
        if self.template is not None:
            self.template = None
            self.energies.value = ("<i>the annotation changed since Solve: press Solve "
                                   "again</i>")
        self.redraw()

    # ------------------------------------------------------------------ painting, polygons
    def paint(self, points, radius=None, erase=False):
        """Paint (or erase) the current region along a stroke through ``points`` (k, 2)
        keyframe px with a brush of ``radius`` px (default: the brush slider); starts a region
        when there is none. Returns the number of pixels changed."""
        P = np.asarray(points, dtype=float).reshape(-1, 2)
        r = float(self.brush.value) if radius is None else number(radius, "radius", lo=0)
        if self._current is None:
            if erase:
                raise ValueError("no region to erase from: press New region first")
            self.new_region()
        mask = self.regions[self._current].mask
        n = sum(_stamp(mask, a, b, r, not erase) for a, b in zip(P, P[1:] if len(P) > 1 else P))
        self._update_joints()
        self._changed()
        return n

    def add_polygon_point(self, x, y):
        """Add a corner ``(x, y)`` (keyframe px) to the polygon being drawn."""
        self._polygon.append(np.array([x, y], dtype=float))
        self._draw_marks()
        self._say(f"{len(self._polygon)} polygon corner(s); Close polygon makes it a region")

    def close_polygon(self, label=""):
        """Make the polygon drawn so far a new region (current); returns its index."""
        if len(self._polygon) < 3:
            raise ValueError(f"a polygon needs at least 3 corners, got {len(self._polygon)}: "
                             "click more corners in polygon mode")
        poly = np.array(self._polygon)
        self._polygon = []
        i = self.add_region(poly, (), label or "polygon")
        self._say(f"region {i}: {int(self.regions[i].mask.sum())} px from the polygon")
        return i

    # ------------------------------------------------------------------ T-junctions
    def toggle_t_junction(self, x, y):
        """A click at ``(x, y)`` (keyframe px) in t-junction mode: remove the T-junction
        within :data:`PICK_PX` canvas px, else add one to the region whose outline is nearest
        (snapped onto it when within ``T_JUNCTION_TOLERANCE`` px) and make that region
        current. Returns ``("added" | "removed", region index, (x, y))``."""
        q = np.array([x, y], dtype=float)
        pick = PICK_PX / self.scale
        best = None
        for i, r in enumerate(self.regions):
            for k, p in enumerate(r.t_junctions):
                d = float(np.linalg.norm(p - q))
                if d <= pick and (best is None or d < best[0]):
                    best = (d, i, k)
        if best is not None:
            _, i, k = best
            p = self.regions[i].t_junctions.pop(k)
            self._select(i)
            self._changed()
            self._say(f"removed the T-junction at ({p[0]:.1f}, {p[1]:.1f}) from region {i} "
                      f"({len(self.regions[i].t_junctions)} left)")
            return "removed", i, tuple(p)
        filled = [i for i, r in enumerate(self.regions) if r.mask.any()]
        if not filled:
            raise ValueError("no occlusion region yet: paint one or draw a polygon first, "
                             "then click T-junctions on its outline")
        snaps = []
        for i in filled:
            P, v, _ = _insert_on_outline(_outline(self.regions[i].mask), q)
            snaps.append((float(np.linalg.norm(P[v] - q)), i, P[v]))
        d, i, on = min(snaps, key=lambda s: s[0])
        p = on if d <= T_JUNCTION_TOLERANCE else q
        self.regions[i].t_junctions.append(np.array(p, float))
        self._select(i)
        self._changed()
        msg = (f"added a T-junction at ({p[0]:.1f}, {p[1]:.1f}) to region {i} "
               f"({len(self.regions[i].t_junctions)} in all)")
        if d > T_JUNCTION_TOLERANCE:
            msg += (f"; it lies {d:.1f} px from the region's outline (Solve needs ≤ "
                    f"{T_JUNCTION_TOLERANCE:g} px)")
        self._say(msg)
        return "added", i, tuple(p)

    # ------------------------------------------------------------------ depth
    def joints_near(self, index=None):
        """Names of the joints within ``near_px`` of region ``index`` (default: the current
        one), nearest first; every joint when there is no (non-empty) region."""
        from scipy import ndimage

        names = list(self._base.names)
        if index is None and self._current is None:
            return names
        mask = self.regions[self._index(index)].mask
        if not mask.any():
            return names
        H, W = mask.shape
        dist = ndimage.distance_transform_edt(~mask)
        ij = np.clip(np.round(self._base.xy[:, ::-1]).astype(int), 0, [H - 1, W - 1])
        d = dist[ij[:, 0], ij[:, 1]]
        return [names[j] for j in np.argsort(d, kind="stable") if d[j] <= self.near_px]

    def set_depth(self, joint, depth):
        """Set the depth of ``joint`` (name or index; smaller = nearer the viewer, Sec. 5.1).
        Joints without a depth so far get 0."""
        j = self._base.index(joint) if isinstance(joint, str) else \
            number(joint, "joint", lo=0, hi=len(self._base) - 1, integer=True)
        value = number(depth, f"depth of {self._base.names[j]!r}")
        if self._depth is None:
            self._depth = np.zeros(len(self._base))
        self._depth[j] = value
        if self.joint.value == self._base.names[j]:
            self._sync_depth_slider()
        self._changed()
        others = [f"{n} {self._depth_of(n):g}" for n in self.joints_near()
                  if n != self._base.names[j]]
        self._say(f"depth of {self._base.names[j]} = {value:g}"
                  + (f" (near the region: {', '.join(others)})" if others else ""))

    def _depth_of(self, name):
        return 0.0 if self._depth is None else float(self._depth[self._base.index(name)])

    def _update_joints(self):
        near = self.joints_near()
        keep = self.joint.value if self.joint.value in near else (near[0] if near else None)
        self._syncing = True
        try:
            self.joint.options = near
            self.joint.value = keep
        finally:
            self._syncing = False
        self._sync_depth_slider()

    def _sync_depth_slider(self):
        if self.joint.value is None:
            return
        d = self._depth_of(self.joint.value)
        self._syncing = True
        try:
            self.depth.min, self.depth.max = min(self.depth.min, d), max(self.depth.max, d)
            self.depth.value = d
        finally:
            self._syncing = False
        self._draw_marks()

    def _on_depth(self, value):
        if not self._syncing and self.joint.value is not None:
            self.set_depth(self.joint.value, value)

    # ------------------------------------------------------------------ mouse
    def _on_mode(self, old):
        if old == "polygon" and self._polygon:
            self._polygon = []
            self._draw_marks()
            self._say("the unfinished polygon was dropped")

    def _on_down(self, x, y):
        """Mouse down at canvas pixel ``(x, y)``."""
        p = self.to_image(x, y)
        mode = self.mode.value
        if mode in ("paint", "erase"):
            self._stroke_changed = self.paint([p], erase=mode == "erase")
            self._stroke = [p]
            self._brush_mark(p)
        elif mode == "polygon":
            self.add_polygon_point(*p)
        else:
            self.toggle_t_junction(*p)

    def _on_move(self, x, y):
        """Mouse move to canvas pixel ``(x, y)``: continues a brush stroke (cheaply: the mask
        layer is redrawn on mouse up)."""
        if self._stroke is None:
            return
        p = self.to_image(x, y)
        if np.linalg.norm(p - self._stroke[-1]) < 0.5:
            return
        mask = self.regions[self._current].mask
        self._stroke_changed += _stamp(mask, self._stroke[-1], p, float(self.brush.value),
                                       self.mode.value == "paint")
        self._stroke.append(p)
        self._brush_mark(p)

    def _on_up(self, x, y):
        """Mouse up at canvas pixel ``(x, y)``: ends a brush stroke."""
        if self._stroke is None:
            return
        self._on_move(x, y)
        self._stroke = None
        i = self._current
        self._update_joints()
        self._changed()
        verb = "painted" if self.mode.value == "paint" else "erased"
        self._say(f"{verb} {self._stroke_changed} px; region {i} has "
                  f"{int(self.regions[i].mask.sum())} px")

    def _brush_mark(self, p):
        layer = self.canvas[1]
        layer.fill_style = COLORS["brush" if self.mode.value == "paint" else "eraser"]
        layer.fill_circle(*self.to_canvas(p), (self.brush.value + 0.5) * self.scale)

    # ------------------------------------------------------------------ drawing
    def redraw(self):
        """Redraw the mask layer and the marks."""
        from ipycanvas import hold_canvas

        H, W = self.image.shape[:2]
        over = np.zeros((H, W, 4), np.uint8)
        for i, r in enumerate(self.regions):
            if i != self._current:
                over[r.mask] = COLORS["mask"]
        if self._current is not None:
            over[self.regions[self._current].mask] = COLORS["current"]
        with hold_canvas():
            self.canvas[1].clear()
            self.canvas[1].put_image_data(self._zoom(over), 0, 0)
            self._draw_marks()

    def _draw_marks(self):
        from ipycanvas import hold_canvas

        layer = self.canvas[2]
        with hold_canvas():
            layer.clear()
            layer.line_cap, layer.line_join = "round", "round"
            for i, r in enumerate(self.regions if self.template is None else ()):
                if r.mask.any():
                    layer.stroke_style = COLORS["outline"]
                    layer.line_width = 2.5 if i == self._current else 1.0
                    layer.stroke_polygon(self.to_canvas(_outline(r.mask)).tolist())
            if self.template is not None:
                self._draw_contours(layer)
            self._draw_skeleton(layer)
            if self._polygon:
                P = self.to_canvas(np.array(self._polygon))
                layer.stroke_style, layer.fill_style = COLORS["polygon"], COLORS["polygon"]
                layer.line_width = 2
                if len(P) > 1:
                    layer.stroke_lines(P.tolist())
                layer.fill_circles(P[:, 0], P[:, 1], 3.5)
            tj = [p for r in self.regions for p in r.t_junctions]
            if tj:
                P = self.to_canvas(np.array(tj))
                layer.fill_style, layer.stroke_style = COLORS["t_junction"], \
                    COLORS["t_junction_edge"]
                layer.line_width = 1.5
                layer.fill_circles(P[:, 0], P[:, 1], 4.5)
                layer.stroke_circles(P[:, 0], P[:, 1], 4.5)

    def _draw_skeleton(self, layer):
        sk, px = self._base, self.to_canvas(self._base.xy)
        layer.stroke_style, layer.line_width = COLORS["bone"], 2
        for p, c in sk.bones:
            layer.stroke_line(*px[p], *px[c])
        near = set(self.joints_near()) if self._current is not None else set()
        for j, name in enumerate(sk.names):
            d = self._depth_of(name)
            layer.fill_style = (COLORS["near"] if d < 0 else COLORS["far"] if d > 0
                                else COLORS["joint"])
            layer.fill_circle(*px[j], 4.0 if name in near else 2.5)
        if self.joint.value is not None:
            j = sk.index(self.joint.value)
            layer.stroke_style, layer.fill_style, layer.line_width = \
                COLORS["selected"], COLORS["selected"], 2
            layer.stroke_circle(*px[j], 8)
            text = f"{self.joint.value} {self._depth_of(self.joint.value):+.1f}"
            layer.font, layer.line_width = "bold 13px sans-serif", 3
            layer.stroke_style = "rgba(255, 255, 255, 0.85)"        # a halo keeps it legible
            layer.stroke_text(text, px[j, 0] + 10, px[j, 1] - 8)
            layer.fill_text(text, px[j, 0] + 10, px[j, 1] - 8)

    def _draw_contours(self, layer):
        """Each region's outline in the solved template: visible contours blue, hidden red
        (Figs. 6 / 8)."""
        for reg in self.template.regions:
            P = self.to_canvas(self.template.X[reg.loop])
            layer.stroke_style, layer.line_width = "white", 7    # a halo under the colours
            layer.stroke_polygon(P)
            segments = np.stack([P, np.roll(P, -1, axis=0)], axis=1)      # (n, 2, 2) edges
            vis = reg.visible_edges()
            layer.line_width = 3.5
            for sel, color in ((vis, COLORS["visible"]), (~vis, COLORS["hidden"])):
                if sel.any():
                    layer.stroke_style = color
                    layer.stroke_line_segments(segments[sel])

    # ------------------------------------------------------------------ solve
    def solve(self):
        """Build the layered template (:func:`~physlab.inbetween.occlusion.
        build_layered_template` with ``target_skeletons=[target_skeleton]``), draw each
        region's outline blue where visible and red where hidden, and list the energies of
        the assignments tried. Returns the :class:`~physlab.inbetween.occlusion.
        LayeredTemplate`."""
        if self.target_skeleton is None:
            raise ValueError("Solve needs the pose to deform into: pass target_skeleton= (e.g. "
                             "the other key's skeleton) to OcclusionAnnotator")
        empty = [i for i, r in enumerate(self.regions) if not r.mask.any()]
        if empty:
            raise ValueError(f"region(s) {empty} are empty: paint them or delete them")
        if not self.regions:
            raise ValueError("no occlusion region to solve: paint one, draw a polygon or "
                             "Suggest")
        self._say("solving…")
        t0 = time.perf_counter()
        try:
            tpl = build_layered_template(self.image, self.skeleton, self.occlusions,
                                         target_skeletons=[self.target_skeleton],
                                         name="keyframe", **self.solve_options)
        except Exception:
            self.template = None
            self.energies.value = ""
            self._draw_marks()
            raise
        self.template = tpl
        self.energies.value = self._energy_report(tpl)
        self._draw_marks()
        vis = sum(int(r.visible_edges().sum()) for r in tpl.regions)
        n = sum(r.n_edges for r in tpl.regions)
        self._say(f"solved in {time.perf_counter() - t0:.1f} s: {vis} visible contour edges "
                  f"(blue), {n - vis} hidden (red)")
        return tpl

    @staticmethod
    def _energy_report(tpl):
        lines = ["<b>Layered template</b> — outline edges: <span style='color:"
                 f"{COLORS['visible']}'>visible</span> / <span style='color:"
                 f"{COLORS['hidden']}'>hidden</span> contours (Figs. 6, 8)"]
        for i, reg in enumerate(tpl.regions):
            k = len(reg.t_junctions)
            vis = int(reg.visible_edges().sum())
            lines.append(f"region {i} {html.escape(repr(reg.label))}")
            lines.append(f"  k = {k} T-junction(s), n = {reg.n_edges} outline edges → "
                         f"{len(reg.energies)} assignment(s) scored (Eq. 2)")
            lines.append(f"  front layer {reg.front}: {vis} visible / {reg.n_edges - vis} "
                         "hidden edges")
            for b, cusp, e in sorted(reg.energies, key=lambda t: t[2]):
                chosen = " ← chosen" if np.array_equal(b, reg.b) else ""
                where = "" if cusp is None else f", cusp at outline vertex {cusp}"
                lines.append(f"  E = {e:10.4f}{where}{chosen}")
        style = "margin:0; font-size:12px; white-space:pre-wrap"
        return f"<pre style='{style}'>" + "\n".join(lines) + "</pre>"

    # ------------------------------------------------------------------ JSON
    def to_json(self):
        """The annotation as JSON text: ``{"occlusions": [...], "joint_depth": {name: d},
        "image_size": [W, H]}`` — the occlusions as
        :func:`~physlab.inbetween.occlusion.save_occlusions` writes them (outline polygons of
        the masks' largest components, T-junctions, labels), so
        :func:`~physlab.inbetween.occlusion.load_occlusions` reads the file too."""
        H, W = self.image.shape[:2]
        data = {"occlusions": [o.to_dict() for o in self.occlusions], "image_size": [W, H]}
        if self._depth is not None:
            data["joint_depth"] = dict(zip(self._base.names, self._depth.tolist()))
        return json.dumps(data, indent=1)

    def save(self, path=None):
        """Write :meth:`to_json` to ``path`` (default: the file box), atomically; returns the
        path."""
        from physlab._io import atomic_write_text

        path = Path(self.file.value if path is None else path)
        atomic_write_text(path, self.to_json())
        skipped = sum(not r.mask.any() for r in self.regions)
        self._say(f"saved {len(self.regions) - skipped} region(s) to {path}"
                  + (f" ({skipped} empty one(s) left out)" if skipped else ""))
        return path

    def load(self, path=None):
        """Replace the annotation by the one in ``path`` (default: the file box). Nothing
        changes when the file is unreadable, of another image size, or names unknown joints."""
        path = Path(self.file.value if path is None else path)
        if not path.is_file():
            raise FileNotFoundError(f"no annotation file at {path}")
        occ = load_occlusions(path)
        data = json.loads(path.read_text(encoding="utf-8"))
        extra = data if isinstance(data, dict) else {}
        H, W = self.image.shape[:2]
        size = extra.get("image_size")
        if size is not None and list(size) != [W, H]:
            raise ValueError(f"{path}: annotation of a {size[0]}x{size[1]} image; this "
                             f"keyframe is {W}x{H}")
        depth = self._depth
        if extra.get("joint_depth") is not None:
            jd = extra["joint_depth"]
            if not isinstance(jd, dict):
                raise ValueError(f"{path}: joint_depth must map joint names to numbers")
            try:
                depth = np.array(self._base.with_depth(
                    {k: number(v, f"joint_depth[{k!r}]") for k, v in jd.items()}).depth)
            except (TypeError, ValueError) as err:
                raise ValueError(f"{path}: {err}") from None
        old = self.regions
        self.regions = []
        try:
            for i, o in enumerate(occ):
                self._append(o, f"{path}: occlusions[{i}]")
        except (TypeError, ValueError):
            self.regions = old
            raise
        self._depth, self._polygon = depth, []
        self._select(len(self.regions) - 1 if self.regions else None)
        self._changed()
        self._say(f"loaded {len(self.regions)} region(s) from {path}")
