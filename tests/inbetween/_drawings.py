"""Tiny synthetic drawings with skeletons for the inbetween tests."""
import json

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


def write_pair(folder, size=96, gt=(0.5,), animation=None, opaque=False, pair=None,
               occlusions=False):
    """A procedural pair as a pair folder (physlab.inbetween.pair_folder): keys, skeletons,
    ``gt_<t>.png`` for every t of ``gt``, ``animation.json`` with ``animation`` frames unless
    None, the keys' true ``occlusions<k>.json`` with ``occlusions``; images RGBA, or RGB on
    white with ``opaque``. ``pair`` default: the first far pair of the benchmark at ``size``.
    Returns the pair."""
    import imageio.v3 as iio

    from physlab.image import over_white, to_uint8
    from physlab.inbetween import inbetween_benchmark, save_occlusions

    def save(path, img):
        iio.imwrite(path, to_uint8(over_white(img)) if opaque else img)

    if pair is None:
        pair = next(p for p in inbetween_benchmark(size=size) if p.kind == "far")
    folder.mkdir(parents=True, exist_ok=True)
    for k, (img, sk) in enumerate(zip(pair.keyframes(), (pair.skeleton0, pair.skeleton1))):
        save(folder / f"key{k}.png", img)
        (folder / f"skeleton{k}.json").write_text(json.dumps(sk.to_dict()))
    for t in gt:
        save(folder / f"gt_{t}.png", pair.ground_truth(t))
    if animation is not None:
        anim = [s.to_dict() for s in pair.animation(animation)]
        (folder / "animation.json").write_text(json.dumps(anim))
    if occlusions:
        for k, occ in enumerate(pair.occlusions()):
            save_occlusions(folder / f"occlusions{k}.json", occ)
    return pair
