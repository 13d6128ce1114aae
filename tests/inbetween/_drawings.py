"""Tiny synthetic drawings with skeletons for the inbetween tests."""
import numpy as np

from physlab.inbetween.skeleton import Skeleton


def bar_drawing(H=120, W=240, x0=30, x1=210, y0=45, y1=75, ink=3):
    """An inked, striped horizontal bar (RGBA uint8) with a 3-joint skeleton along its axis."""
    yy, xx = np.mgrid[0:H, 0:W]
    inside = (xx >= x0) & (xx <= x1) & (yy >= y0) & (yy <= y1)
    border = inside & ~((xx >= x0 + ink) & (xx <= x1 - ink) & (yy >= y0 + ink) & (yy <= y1 - ink))
    img = np.zeros((H, W, 4), np.uint8)
    stripes = ((xx // 8) % 2).astype(bool)
    img[inside] = (230, 120, 60, 255)
    img[inside & stripes] = (250, 200, 90, 255)
    img[border] = (20, 20, 30, 255)
    yc = 0.5 * (y0 + y1)
    sk = Skeleton(("shoulder", "elbow", "hand"), [-1, 0, 1],
                  [[x0 + 10, yc], [0.5 * (x0 + x1), yc], [x1 - 10, yc]])
    return img, sk


def bend(sk, degrees):
    """The bar's skeleton with the elbow bent by ``degrees`` (positive: clockwise on screen)."""
    a = sk.local_angles().copy()
    a[sk.index("hand")] += np.radians(degrees)
    return Skeleton.from_local(sk.names, sk.parents, sk.xy[sk.root], a, sk.bone_lengths())
